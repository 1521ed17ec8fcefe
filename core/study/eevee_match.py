"""Match EEVEE's subsurface scattering to Cycles' random walk, per material: the numbers.

EEVEE reads a Principled BSDF's Radius r and Scale S as d = (r S / 4π) / s(A) per channel, with
s(A) the diffuse-surface-transmission fit of Christensen and Burley (docs/references.md §1, §18),
whatever the subsurface method, and gathers over a fixed 16-sample spiral. ``blender/match_eevee.py``
gives each material an EEVEE-only copy of its shader whose inputs make EEVEE gather over k times
its own d as authored, with the Base Color times a gain g per channel, and picks k and g so that
EEVEE's SSS effect matches Cycles' on the scene's own frame (k = 1 and g = 1 is the material as
authored, so the match starts from it). This module holds the arithmetic, without Blender:

- ``eevee_d`` / ``eevee_radius``: EEVEE's d from its inputs and the Radius that gives a wanted d;
- ``solve_gain``: for one trial k, the per-channel g minimizing the squared difference between
  EEVEE's image with the gain and the target (EEVEE without scattering plus Cycles' SSS effect),
  over the material's 2 x 2 block means (the error measure's blocks, docs/references.md §8):
  EEVEE applies the albedo after the blur, so with d held (``eevee_radius`` at the new colour)
  its image is linear in g: E(g) = E_rest + g (E_1 - E_rest), E_rest the image with the Base Color
  black (what the albedo does not scale: the specular layer, other materials);
- ``view_table`` / ``view_factor``: the entry's dependence on the view angle that Cycles' walk
  shows and EEVEE's gather does not (docs/references.md §15, ``core.optics.energy.entry_gain``:
  a random walk returns less light seen straight on than at a grazing angle), as the stops of a
  Color Ramp on the view cosine that the branch multiplies the Base Color with, and the same
  factor per pixel for the solve: with it E(g) = E_rest + g F (E_1 - E_rest), still linear in g;
- ``effect_removed``: the share of Cycles' SSS effect an EEVEE pair (with and without scattering)
  reproduces, 1 - |(E_sss - E_none) - (C_sss - C_none)| / |C_sss - C_none| over the material's
  blocks, the *removed* of the fidelity suite with EEVEE's change in place of a technique's.
"""

from __future__ import annotations

import math

import numpy as np

from ..optics.energy import VIEW_DEG, entry_gain
from ..optics.profiles import albedo_scaling
from .metrics import box_downsample

#: The trial scales of EEVEE's own d for the material as authored (1: as authored, the gains alone),
#: in octaves up to 16, past SSS Lab's d (4π = 12.6 times EEVEE's).
K_GRID = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)
#: Bounds of the per-channel gain on the Base Color (the fit's own, ``core/scene/fit_values.py``).
GAIN_RANGE = (0.25, 4.0)
#: Blocks of the measure, as the error measure and the fit (docs/references.md §8).
BOX = 2


def eevee_d(radius, scale: float, base_color) -> np.ndarray:
    """EEVEE's d per channel (scene units) for Radius ``radius`` (R, G, B), Scale ``scale`` and
    Base Color ``base_color``: (r S / 4π) / s(A) (docs/references.md §18)."""
    r = np.asarray(radius, np.float64) * float(scale)
    return r / (4.0 * math.pi) / albedo_scaling(np.clip(np.asarray(base_color, np.float64), 0.0, 1.0))


def eevee_radius(d, scale: float, base_color) -> np.ndarray:
    """The Radius (R, G, B) that makes EEVEE gather over ``d`` with Scale ``scale`` and Base Color
    ``base_color``: the inverse of ``eevee_d``. ``scale`` must be > 0."""
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale: expected a number > 0, got {scale!r}")
    s = albedo_scaling(np.clip(np.asarray(base_color, np.float64), 0.0, 1.0))
    return np.asarray(d, np.float64) * 4.0 * math.pi * s / float(scale)


def view_table(method: str, albedo) -> tuple[np.ndarray, np.ndarray] | None:
    """(view cosines ascending (n,), factors (n, 3) per channel, each channel's largest 1): the entry
    gain of Cycles' ``method`` for Base Color ``albedo`` at the table's own view angles, so that a
    linear ramp between them reads what ``entry_gain`` reads; None for a method whose light does
    not depend on the view angle (Christensen-Burley, measured equal to Lambert)."""
    mu = np.cos(np.radians(np.asarray(VIEW_DEG[::-1], np.float64)))
    a = np.broadcast_to(np.clip(np.asarray(albedo, np.float64), 0.0, 1.0), mu.shape + (3,))
    gain = entry_gain(method, a, mu).astype(np.float64)
    if np.allclose(gain, 1.0):
        return None
    return mu, gain / gain.max(axis=0)


def view_factor(cos_view, table: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The ramp of ``view_table`` read at each pixel's view cosine ``cos_view`` (H, W), clamped at
    its ends like a Color Ramp: (H, W, 3) float64 (NaN reads the straight-on end)."""
    mu, factors = table
    c = np.nan_to_num(np.abs(np.asarray(cos_view, np.float64)), nan=1.0)
    return np.stack([np.interp(c, mu, factors[:, k]) for k in range(3)], axis=-1)


def _blocks(image: np.ndarray, keep: np.ndarray) -> np.ndarray:
    return box_downsample(np.asarray(image[..., :3], np.float64), BOX)[keep]


def material_blocks(mask: np.ndarray) -> np.ndarray:
    """The 2 x 2 blocks wholly inside ``mask`` (the material's pixels)."""
    return box_downsample(mask.astype(np.float64), BOX) >= 1.0


def solve_gain(e_one, e_rest, target, keep) -> tuple[np.ndarray, float]:
    """(g per channel within ``GAIN_RANGE``, the relative RMS error left) of
    E_rest + g (E_one - E_rest) against ``target`` on the blocks ``keep``; a channel whose
    scattered light is nil keeps g = 1."""
    one, rest, t = _blocks(e_one, keep), _blocks(e_rest, keep), _blocks(target, keep)
    light = one - rest
    ll = np.sum(light * light, axis=0)
    g = np.where(ll > 0, np.sum(light * (t - rest), axis=0) / np.where(ll > 0, ll, 1.0), 1.0)
    g = np.clip(g, *GAIN_RANGE)
    model = rest + g * light
    mean = float(np.mean(t))
    error = float(np.sqrt(np.mean((model - t) ** 2))) / mean if mean > 0 else math.nan
    return g, error


def effect_removed(e_sss, e_none, c_sss, c_none, keep) -> float | None:
    """The share of Cycles' SSS effect (``c_sss`` - ``c_none``) that EEVEE's (``e_sss`` -
    ``e_none``) reproduces on the blocks ``keep``; None where Cycles' effect is nil there."""
    cycles = _blocks(c_sss, keep) - _blocks(c_none, keep)
    eevee = _blocks(e_sss, keep) - _blocks(e_none, keep)
    size = float(np.sqrt(np.sum(cycles * cycles)))
    if not size > 0:
        return None
    return 1.0 - float(np.sqrt(np.sum((eevee - cycles) ** 2))) / size


def target_image(e_none, c_sss, c_none) -> np.ndarray:
    """What EEVEE with scattering should show: EEVEE without it plus Cycles' SSS effect (RGB)."""
    return np.asarray(e_none[..., :3], np.float64) + (
        np.asarray(c_sss[..., :3], np.float64) - np.asarray(c_none[..., :3], np.float64)
    )
