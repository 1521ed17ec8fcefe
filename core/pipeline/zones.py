"""A pixel's own profile width where a material's inputs vary over it.

When a material's Base Color, Subsurface Radius or Scale is linked to a texture (read per pixel
from the render, ``core.scene.inputs``), the profile's d differs from pixel to pixel: Cycles'
random walk scatters each point with its own radius and albedo, and the real-time engines give
each pixel its own scatter radius. ``zones`` computes each pixel's d from its own inputs (the
same mapping as the material's, ``core.pipeline.mapping``) and, where d spreads by more than
``MIN_SPREAD`` over the material, splits the material's pixels into ``ZONES`` groups of equal
count by their d. Each zone is computed with the inputs of its own pixels (per channel, their
median Radius x Scale and Base Color), gathering light from the whole material, and keeps the
result on its own pixels: the profile at a pixel is that pixel's, to within the zone's spread,
as in a gather whose kernel width is read at the pixel it computes.

A material whose d spreads less, or whose inputs are typed in, is one zone (nothing more to
compute). Pixels on the material's silhouette, whose AOVs hold the value times the pixel's
coverage, join the zone of the material's median d.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..base import arrays
from ..scene.exr import Passes
from ..scene.inputs import interior, usable_map
from ..scene.scene import MaterialSSS
from . import mapping as _mapping

#: Zones a material with varying d is split into, and the spread of d (ratio of its 90th to its
#: 10th percentile over the material's pixels) below which it stays one: 15 % is below what a
#: profile's width changes in the fidelity suite between its mappings.
ZONES = 4
MIN_SPREAD = 1.15
#: The inputs that change d.
D_INPUTS = ("base_color", "subsurface_radius", "subsurface_scale")


@dataclasses.dataclass
class Zone:
    """Pixels of one material computed with one set of inputs."""

    #: bool (H, W): the pixels that keep this zone's result.
    pixels: np.ndarray
    #: The material with this zone's inputs (Radius x Scale and Base Color of its pixels).
    material: MaterialSSS
    #: The zone's d per channel (scene units), for ``explain``.
    d_su: tuple


def zones(material: MaterialSSS, passes: Passes, mask: np.ndarray, mapping=None) -> tuple[list[Zone], str | None]:
    """(the zones of ``material``'s pixels ``mask``, a line for the plan's notes), or ([], None)
    when the material is one zone: none of its d inputs is read per pixel, or d spreads less than
    ``MIN_SPREAD``."""
    varying = [k for k in D_INPUTS if k in material.per_pixel]
    if not varying:
        return [], None
    inner = interior(mask)
    n = int(np.count_nonzero(inner))
    if n < ZONES * 4:
        return [], None
    radius = np.broadcast_to(np.asarray(material.subsurface_radius, np.float64), (n, 3)).copy()
    scale = np.full((n, 1), float(material.subsurface_scale))
    color = np.broadcast_to(np.asarray(material.base_color, np.float64), (n, 3)).copy()
    for key, target in (("subsurface_radius", radius), ("subsurface_scale", scale), ("base_color", color)):
        if key in varying:
            values = usable_map(material, passes, key, inner)
            if values is not None:
                target[...] = values.reshape(target.shape)
    radius_su = radius * scale
    d = _mapping.burley_d_pixels(material.method, radius_su, color, float(material.subsurface_ior), mapping)
    log_d = np.mean(np.log(np.maximum(d, 1e-30)), axis=1)
    lo, hi = np.percentile(log_d, (10, 90))
    spread = float(np.exp(hi - lo))
    if not np.isfinite(spread) or spread < MIN_SPREAD:
        return [], None
    edges = np.quantile(log_d, np.linspace(0.0, 1.0, ZONES + 1)[1:-1])
    which = np.searchsorted(edges, log_d, side="right")  # 0 .. ZONES - 1
    middle = int(which[np.argmin(np.abs(log_d - np.median(log_d)))])  # a zone that has pixels
    label = np.full(mask.shape, -1, np.int64)
    label[mask] = middle  # the silhouette: the median's zone
    label[inner] = which
    result = []
    for z in range(ZONES):
        here = which == z
        if not here.any():
            continue
        zone_material = dataclasses.replace(
            material,
            subsurface_radius=tuple(arrays.median(np.array(radius_su[here, c])) for c in range(3)),
            subsurface_scale=1.0,
            base_color=tuple(min(arrays.median(np.array(color[here, c])), 1.0) for c in range(3)),
        )
        d_zone = tuple(float(v) for v in _mapping.burley_d(zone_material, mapping=mapping))
        result.append(Zone(pixels=label == z, material=zone_material, d_su=d_zone))
    widths = ", ".join("/".join(f"{v:.3g}" for v in zone.d_su) for zone in result)
    note = (
        f"d per pixel: its inputs vary over the material (d spreads {spread:.2f}x between its 10th and 90th "
        f"percentile), so its pixels are computed in {len(result)} zones by their own d (R/G/B, scene units: {widths})"
    )
    return result, note
