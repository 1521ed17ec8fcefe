"""The slide deck's visual-fidelity table, measured instead of asserted.

The slide deck (docs/references.md §12, its section 04) rates each technique on three properties. Here each is a
number from one synthetic experiment: a flat, fully masked, white (albedo 1) surface seen by an
orthographic camera, lit only along one vertical line of pixels.

- **Non-local diffusion**: how far light spreads from the lit line — the distance from the line
  within which 90 % of the light that leaves the surface is found (``r90_su``, per channel, scene
  units). 0 means the technique is local.
- **Distance-dependent colour bleeding**: whether the channels spread differently —
  ``bleeding_ratio`` = red r90 / blue r90 (1 = no colour bleeding).
- **Energy conservation**: light leaving the surface over light arriving (``energy_ratio``, per
  channel; 1 = conserving, above 1 = adds light).

STA does not take the lit line as input at all (it adds back-lighting from a thickness map), so
for it the same surface gets a back light, full translucency, and the same lit line: the added
light lands on every pixel regardless of the line (local: r90 0 from the line's own light, no
per-channel spread) and the energy ratio shows how much it adds.

A row "Burley profile (analytic)" gives the same numbers for the diffusion profile itself,
integrated in closed form along the line — what a faithful technique should reproduce.
"""

from __future__ import annotations

import math

import numpy as np

from ..optics.profiles import burley_cdf
from ..pipeline import mapping as _mapping
from ..pipeline.call import call_technique
from ..scene.scene import Camera, Light, MaterialSSS
from ..techniques.registry import TECHNIQUES, get_spec
from ..techniques.spec import Technique

DEFINITION = (
    "A flat, white, fully masked surface under an orthographic camera, lit along one vertical line of pixels."
    " r90: distance from the line holding 90 % of the outgoing light (0 = local); colour bleeding: red r90 / blue"
    " r90 (1 = none); energy: outgoing over incoming light (1 = conserving). STA gets a back light and full"
    " translucency as its input instead (it ignores the lit line)."
)

#: Half-width of the test image in pixels, and the share of it the widest kernel (16 d) covers.
_HALF = 96
_KERNEL_SHARE = 0.75


def _r90(profile: np.ndarray, centre: int, px_per_unit: float) -> float:
    """Smallest distance from ``centre`` (in scene units) holding 90 % of ``profile``'s sum."""
    p = np.clip(np.nan_to_num(profile.astype(np.float64)), 0.0, None)
    total = p.sum()
    if total <= 0:
        return 0.0
    for r in range(len(p)):
        lo, hi = max(centre - r, 0), min(centre + r + 1, len(p))
        if p[lo:hi].sum() >= 0.9 * total:
            return r / px_per_unit
    return (len(p) // 2) / px_per_unit


def _setup(d_max_su: float):
    n = 2 * _HALF + 1
    px_per_unit = _KERNEL_SHARE * _HALF / (16.0 * d_max_su)
    camera = Camera(type="ORTHO", width_px=n, height_px=n, ortho_scale=n / px_per_unit)
    diffuse = np.zeros((n, n, 3), dtype=np.float32)
    diffuse[:, _HALF, :] = 1.0
    return n, px_per_unit, camera, diffuse


def analytic_row(d_su) -> dict:
    """The Burley profile's own numbers: the line-spread function's 90 % distance per channel.

    A line source spreads as the profile integrated along the line; the fraction within
    distance x of the line is the 2-D profile's mass in the strip |X| < x, computed here by
    integrating the radial CDF over angle: P(|X| < x) = 1 - (2/pi) int_0^{pi/2} (1 - CDF(x / cos t)) dt.
    """
    r90 = []
    t = (np.arange(2000) + 0.5) / 2000 * (math.pi / 2)  # midpoint rule over the angle
    for d in np.broadcast_to(np.asarray(d_su, dtype=np.float64), (3,)):
        if d <= 0:
            r90.append(0.0)
            continue

        def strip(x, d=d):
            return 1.0 - (2.0 / math.pi) * np.sum(1.0 - burley_cdf(x / np.cos(t), d)) * (math.pi / 2) / len(t)

        lo, hi = 0.0, 40.0 * d
        for _ in range(60):  # bisection to relative 1e-18 of the bracket
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if strip(mid) < 0.9 else (lo, mid)
        r90.append(0.5 * (lo + hi))
    return {"r90_su": r90, "bleeding_ratio": r90[0] / r90[2] if r90[2] > 0 else None, "energy_ratio": [1.0] * 3}


def measure(technique: str | Technique, material: MaterialSSS, *, mapping=None, options=None) -> dict:
    """One row of the table for ``technique`` with ``material``'s parameters (and ``options``,
    keyword arguments of the technique that replace its defaults, e.g. Burley's ``seed``)."""
    d = np.broadcast_to(np.asarray(_mapping.burley_d(material, mapping=mapping), dtype=np.float64), (3,))
    d_max = float(d.max()) if d.max() > 0 else 1e-3
    n, ppu, camera, diffuse = _setup(d_max)
    albedo = np.ones_like(diffuse)
    depth = np.ones((n, n), dtype=np.float32)
    mask = np.ones((n, n), dtype=bool)
    spec = get_spec(technique)
    if not spec.scatters:  # it adds light only: measured on light from behind
        normal = np.zeros_like(diffuse)
        normal[..., 2] = 1.0  # facing the camera, which looks down -Z from +Z
        position = np.zeros_like(diffuse)
        # A sun turned 180 degrees about X shines along +Z: through the surface toward the camera.
        back = Light(
            type="SUN", name="back", energy=1.0, matrix_world=(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1)
        )
        params = {**_mapping.technique_params(material, spec, mapping=mapping), **(options or {})}
        if spec.prepare is not None:  # e.g. STA without a bake distance: the paper's map
            spec.prepare(params)
        added = np.asarray(
            call_technique(
                spec,
                **params,
                albedo=albedo,
                normal=normal,
                position=position,
                thickness=np.ones((n, n), np.float32),
                mask=mask,
                camera=camera,
                lights=(back,),
            ),
            dtype=np.float64,
        )
        incoming = diffuse.astype(np.float64)
        out = incoming + added
        line_part = out - added  # the line's own light: STA does not move it
        mid = line_part[n // 2]
    else:
        params = {**_mapping.technique_params(material, spec, mapping=mapping), **(options or {})}
        # A technique that also adds light is measured on its diffusion alone: no light from behind.
        params |= spec.diffusion_only
        # The table measures how the technique moves the passes' light: without the Cycles method's
        # energy (core/optics/energy.py), a per-pixel gain measured and reported apart.
        if "energy" in spec.keywords:
            params["energy"] = "lambert"
        out = np.asarray(
            call_technique(spec, diffuse=diffuse, albedo=albedo, depth=depth, mask=mask, camera=camera, **params),
            dtype=np.float64,
        )
        incoming = diffuse.astype(np.float64)
        mid = out[n // 2]
    # Energy over the rows away from the top/bottom borders, where the image ends the kernel.
    rows = slice(n // 4, 3 * n // 4)
    energy = [float(out[rows, :, c].sum() / incoming[rows, :, c].sum()) for c in range(3)]
    r90 = [_r90(mid[:, c], _HALF, ppu) for c in range(3)]
    return {
        "r90_su": r90,
        "bleeding_ratio": (r90[0] / r90[2]) if r90[2] > 0 else (1.0 if r90[0] == 0 else None),
        "energy_ratio": energy,
    }


def fidelity_table(material: MaterialSSS, *, techniques=tuple(TECHNIQUES), mapping=None) -> dict:
    """The table for ``material``: one row per technique plus the analytic profile."""
    rows = {get_spec(t).label: measure(t, material, mapping=mapping) for t in techniques}
    rows["Burley profile (analytic)"] = analytic_row(_mapping.burley_d(material, mapping=mapping))
    return {"definition": DEFINITION, "material": material.name, "rows": rows}
