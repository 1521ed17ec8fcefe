"""What the SSSS and Burley node groups share: their interface, the albedo modes, compositing.

Both scatter the diffuse light E = diffuse + diffuse_indirect of the masked pixels with
Convolve nodes and rebuild the image as ``core.pipeline.apply`` does: on the mask,
Image - albedo x E + post x scatter(light), with (light, post) = (E, albedo) for
``albedo_mode`` "post" and (sqrt(albedo) E, sqrt(albedo)) for "pre-post".

Masking, so that light neither leaves nor enters the mask (``core.techniques.ssss.technique`` /
``core.techniques.burley.technique``),
with M the mask and conv a Convolve node:

- SSSS, per 1-D pass (weight of taps off the mask goes to the centre pixel, as ``core.techniques.ssss.technique``):
  pass(L) = conv(L M) + (1 - conv(M)) L;
- Burley (taps off the mask are dropped and the rest renormalized, as ``core.techniques.burley.technique``):
  conv(L M) / conv(M).

Outside the image the Convolve node reads zeros, which the same formulas treat as pixels off
the mask.
"""

from __future__ import annotations

from ..core.pipeline.apply import ALBEDO_MODES
from . import _graph
from ._graph import Interface, Socket


def interface(description: str) -> Interface:
    return Interface(
        inputs=[
            Socket("Image", "COLOR", (0.0, 0.0, 0.0, 1.0), "The image the scattered light replaces the diffuse in"),
            Socket("diffuse", "COLOR", (0.0, 0.0, 0.0, 1.0), "Diffuse Direct pass (diffuse light)"),
            Socket("diffuse_indirect", "COLOR", (0.0, 0.0, 0.0, 1.0), "Diffuse Indirect pass (added to diffuse)"),
            Socket("albedo", "COLOR", (0.8, 0.8, 0.8, 1.0), "Diffuse Color pass"),
            Socket("mask", "FLOAT", 1.0, "1 on the material's pixels, 0 elsewhere", 0.0, 1.0),
            Socket(
                "albedo_mode",
                "MENU",
                "post",
                "post: albedo after scattering; pre-post: its square root before and after",
                items=ALBEDO_MODES,
            ),
        ],
        outputs=[
            Socket("Image", "COLOR", description=description),
            Socket("SSS", "COLOR", description="Scattered minus original diffuse light, on the mask"),
        ],
    )


class ScatterGraph(_graph.Graph):
    """A Graph with the shared inputs already computed: ``light``, ``mask_rgb`` and ``post``."""

    def __init__(self, group):
        super().__init__(group)
        diffuse = self.vadd(self.inp("diffuse"), self.inp("diffuse_indirect"), label="E")
        albedo = self.inp("albedo")
        root = self.vmath("POWER", self.vmath("MAXIMUM", albedo, (0.0, 0.0, 0.0)), (0.5, 0.5, 0.5), label="sqrt A")
        mode = self.inp("albedo_mode")
        self.light = self.menu("VECTOR", mode, {"post": diffuse, "pre-post": self.vmul(root, diffuse)}, "light")
        self.post = self.menu("VECTOR", mode, {"post": albedo, "pre-post": root}, "post")
        self.original = self.vmul(albedo, diffuse, label="A E (in Image)")
        self.mask = self.inp("mask")
        self.mask_rgb = self.gray(self.mask, label="M")
        self.column()

    def finish(self, scattered) -> None:
        """Outputs from the scattered light (before the post factor)."""
        self.column()
        out = self.vmul(self.post, scattered, label="post x scattered")
        sss = self.vscale(self.vsub(out, self.original), self.mask, label="SSS")
        self.column()
        self.out("SSS", sss)
        self.out("Image", self.add_keep_alpha(self.inp("Image"), sss))
