"""SSSS as a compositor node group: two 1-D Convolve passes with per-channel kernel images.

The kernel is ``core.optics.kernels.make_kernel`` (the same parameters, names and defaults as
``core.techniques.ssss.technique.ssss``: ``kernel_type``, ``n_taps``, ``d_su`` and the artist kernel's ``unit_su``,
``falloff``, ``strength``), laid out at a fixed ``pixels_per_unit`` by
``core.optics.kernel_images.separable_kernel_image``: a 1-pixel-high image for the horizontal pass and
a 1-pixel-wide one for the vertical pass, each channel's weights in its colour channel (the
Convolve node's Color kernel convolves R with R, G with G, B with B). The masking and compositing
are in ``nodes/_scatter.py``.

Differences from ``core.techniques.ssss.technique`` (measured in docs/compositor.md): the kernel has one size for
the whole image (``pixels_per_unit`` at one depth) instead of scaling with each pixel's depth;
no follow-surface (taps across a depth jump on the mask still count); at the image border taps
off the image give their weight to the centre pixel (``core.techniques.ssss.technique`` reads the edge pixel).
"""

from __future__ import annotations

import numpy as np

from ..core.optics.kernel_images import separable_kernel_image
from ..core.optics.kernels import check_taps, make_kernel
from ..core.techniques.ssss.technique import TECHNIQUE
from . import _graph, _scatter

GROUP_NAME = "SSS Lab SSSS"
VERSION = 1
INTERFACE = _scatter.interface("Image with the diffuse light of the mask replaced by the separable SSS")


#: The kernel's defaults: SSSS's own (its function's signature, through its spec).
_DEFAULTS = TECHNIQUE.defaults


def ssss_kernel_images(
    *,
    pixels_per_unit: float,
    d_su=None,
    kernel_type: str = _DEFAULTS["kernel_type"],
    n_taps: int = _DEFAULTS["n_taps"],
    unit_su: float | None = None,
    falloff=None,
    strength=None,
) -> tuple[np.ndarray, np.ndarray]:
    """(horizontal (1, 2R+1, 3), vertical (2R+1, 1, 3)) kernel images, row 0 at the top."""
    check_taps(n_taps)
    kernel = make_kernel(kernel_type, n_taps, d_su=d_su, unit_su=unit_su, falloff=falloff, strength=strength)
    line = separable_kernel_image(kernel, pixels_per_unit)
    return line[None, :, :], line[:, None, :]


def ensure_ssss_group(
    *,
    pixels_per_unit: float,
    d_su=None,
    kernel_type: str = _DEFAULTS["kernel_type"],
    n_taps: int = _DEFAULTS["n_taps"],
    unit_su: float | None = None,
    falloff=None,
    strength=None,
    name: str = GROUP_NAME,
):
    """The SSSS node group ``name`` for these kernel parameters, built or rebuilt in place
    (idempotent: the group, its nodes and its two kernel images are reused); returns it.

    ``pixels_per_unit``: the kernel's fixed screen scale (``core.scene.scene.Camera.pixels_per_unit``
    at the depth of the surface). The parameters are stored on the group (``group["sss_lab"]``).
    """
    h_img, v_img = ssss_kernel_images(
        pixels_per_unit=pixels_per_unit,
        d_su=d_su,
        kernel_type=kernel_type,
        n_taps=n_taps,
        unit_su=unit_su,
        falloff=falloff,
        strength=strength,
    )
    meta = {
        "technique": "ssss",
        "version": VERSION,
        "pixels_per_unit": float(pixels_per_unit),
        "kernel_type": kernel_type,
        "n_taps": int(n_taps),
        "kernel_radius_px": int(h_img.shape[1] // 2),
    }
    for key, value in (("d_su", d_su), ("unit_su", unit_su), ("falloff", falloff), ("strength", strength)):
        if value is not None:
            meta[key] = [float(v) for v in np.atleast_1d(np.asarray(value, dtype=np.float64))]
    group = _graph.ensure_group(name, INTERFACE, meta)
    h = _graph.ensure_image(f"{name} kernel H", h_img, owner=name)
    v = _graph.ensure_image(f"{name} kernel V", v_img, owner=name)
    g = _scatter.ScatterGraph(group)
    once = _pass(g, g.light, h, "horizontal")
    g.column()
    twice = _pass(g, once, v, "vertical")
    g.finish(twice)
    _graph.set_menu_defaults(group, INTERFACE)
    return group


def _pass(g, light, kernel_image, label: str):
    """conv(L M) + (1 - conv(M)) L: taps off the mask give their weight to the centre pixel."""
    gathered = g.convolve(g.vmul(light, g.mask_rgb), kernel_image, label=f"{label} L M")
    reach = g.convolve(g.mask_rgb, kernel_image, label=f"{label} M")
    missing = g.vsub((1.0, 1.0, 1.0), reach, label="off-mask weight")
    return g.vadd(gathered, g.vmul(missing, light), label=f"{label} pass")
