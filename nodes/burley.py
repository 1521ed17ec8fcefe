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

Two routes (``route``):

- ``"convolve"``: the profile as a kernel image in Convolve nodes (exact to the pixel; the
  compositor runs Convolve as an FFT on the CPU even when it runs on the GPU);
- ``"gaussians"``: the profile as the pixel itself plus six Gaussians
  (``core.optics.kernel_images.burley_gaussian_mixture``), one Blur node each, with the mask
  carried in the alpha channel so that one blur serves the light and its renormalization: the
  costly part runs wherever the compositor runs, the GPU included. Its kernel differs from the
  exact one by the fit (measured in docs/compositor.md).
"""

from __future__ import annotations

from ..core.optics.kernel_images import burley_gaussian_mixture, burley_kernel_image
from . import _graph, _scatter

GROUP_NAME = "SSS Lab Burley"
VERSION = 2
#: The routes of the group: Convolve nodes with the exact kernel, or Blur nodes' Gaussians.
ROUTES = ("convolve", "gaussians")
INTERFACE = _scatter.interface("Image with the diffuse light of the mask replaced by Burley diffusion")


def ensure_burley_group(*, d_su, pixels_per_unit: float, route: str = "convolve", name: str = GROUP_NAME):
    """The Burley node group ``name`` for the profile ``d_su`` (R, G, B, scene units) at
    ``pixels_per_unit``, built or rebuilt in place (idempotent: the group, its nodes and its
    kernel image are reused); returns it. ``route``: one of ``ROUTES`` (module docstring). The
    parameters are stored on the group."""
    if route not in ROUTES:
        raise ValueError(f"route: expected one of {', '.join(ROUTES)}, got {route!r}")
    if route == "gaussians":
        return _ensure_gaussians(d_su, pixels_per_unit, name)
    image = burley_kernel_image(d_su, pixels_per_unit)
    meta = {
        "technique": "burley",
        "version": VERSION,
        "route": route,
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


def _ensure_gaussians(d_su, pixels_per_unit: float, name: str):
    """The Blur-node route: sum_k w_k G_k(L M) / sum_k w_k G_k(M) per channel, k = 0 the pixel
    itself, each G_k one Blur node over (L M, M) packed as RGB and alpha."""
    sizes, weights = burley_gaussian_mixture(d_su, pixels_per_unit)
    meta = {
        "technique": "burley",
        "version": VERSION,
        "route": "gaussians",
        "d_su": [float(v) for v in d_su],
        "pixels_per_unit": float(pixels_per_unit),
        "kernel_radius_px": int(max(sizes, default=0)),
        "blur_sizes": [int(s) for s in sizes],
        "weights": [[float(v) for v in row] for row in weights],
    }
    group = _graph.ensure_group(name, INTERFACE, meta)
    g = _scatter.ScatterGraph(group)
    lm = g.vmul(g.light, g.mask_rgb, label="L M")
    gathered = g.vmul(lm, tuple(weights[0]), label="w0 L M")
    reach = g.vmul(g.mask_rgb, tuple(weights[0]), label="w0 M")
    packed = g.with_alpha(lm, g.mask, label="L M, M in alpha")
    for k, size in enumerate(sizes, start=1):
        g.column()
        blurred = g.blur(packed, size, label=f"Gaussian {size} px")
        gathered = g.vadd(gathered, g.vmul(blurred, tuple(weights[k])), label=f"+ w{k} G(L M)")
        reach = g.vadd(reach, g.vscale(tuple(weights[k]), g.alpha(blurred)), label=f"+ w{k} G(M)")
    g.column()
    g.finish(g.vmath("DIVIDE", gathered, reach, label="renormalized"))
    _graph.set_menu_defaults(group, INTERFACE)
    return group
