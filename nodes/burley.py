"""Burley as a compositor node group: one Convolve with a 2-D per-channel profile image.

The kernel image is the Christensen-Burley profile of ``d_su`` integrated over each pixel at a
fixed ``pixels_per_unit`` (``core.optics.kernel_images.burley_kernel_image``): what
``core.techniques.burley.technique.burley``
converges to with many samples on a constant-depth surface, without its sampling noise or
banding. Off-mask pixels are dropped and the rest renormalized, conv(L M) / conv(M), as the
NumPy estimator renormalizes rejected samples; masking and compositing: ``nodes/_scatter.py``.

Differences from ``core.techniques.burley.technique`` (measured in docs/compositor.md): one kernel size for the
whole image instead of one per pixel depth; no 3-D distance across depth jumps and no object-id
rejection (only the mask separates surfaces); what lies off the mask is dropped whether it is in
front of a pixel or behind it (``core.techniques.burley.technique`` counts the pixel's own light for a sample hidden
by something in front); the exact profile instead of ``n_samples`` spiral samples
(``n_samples``, ``random_rotation`` and ``seed`` do not apply).
"""

from __future__ import annotations

from ..core.optics.kernel_images import burley_kernel_image
from . import _graph, _scatter

GROUP_NAME = "SSS Lab Burley"
VERSION = 1
INTERFACE = _scatter.interface("Image with the diffuse light of the mask replaced by Burley diffusion")


def ensure_burley_group(*, d_su, pixels_per_unit: float, name: str = GROUP_NAME):
    """The Burley node group ``name`` for the profile ``d_su`` (R, G, B, scene units) at
    ``pixels_per_unit``, built or rebuilt in place (idempotent: the group, its nodes and its
    kernel image are reused); returns it. The parameters are stored on the group."""
    image = burley_kernel_image(d_su, pixels_per_unit)
    meta = {
        "technique": "burley",
        "version": VERSION,
        "d_su": [float(v) for v in d_su],
        "pixels_per_unit": float(pixels_per_unit),
        "kernel_radius_px": int(image.shape[0] // 2),
    }
    group = _graph.ensure_group(name, INTERFACE, meta)
    kernel = _graph.ensure_image(f"{name} kernel", image, owner=name)
    g = _scatter.ScatterGraph(group)
    gathered = g.convolve(g.vmul(g.light, g.mask_rgb), kernel, label="L M")
    weight = g.convolve(g.mask_rgb, kernel, label="M")
    g.column()
    g.finish(g.vmath("DIVIDE", gathered, weight, label="renormalized"))
    _graph.set_menu_defaults(group, INTERFACE)
    return group
