"""Separable SSS kernels: tap offsets and per-channel weights (no Blender).

Both kernels of Jimenez et al., "Separable Subsurface Scattering" (Computer Graphics Forum
34(6), 2015; reference code iryoku/separable-sss), docs/references.md §3:

- ``artist_kernel``: the sum of five Gaussians fit to skin (d'Eon 2007), each channel widened by
  its falloff, the centre tap blended towards identity by the strength, as in the reference code.
- ``preintegrated_kernel``: built offline from the Burley profile (``core.optics.profiles``): the 2-D
  profile integrated over each pair of tap footprints, then reduced to one 1-D kernel per
  channel: by default its marginal (exact line and edge spread), or the first
  singular vector (a rank-1 least-squares fit). The paper does not spell
  out its exact construction (docs/references.md §3); both readings are here and measured.

Offsets are shared by the channels and denser near the centre (quadratic spacing, as in the
reference code); the weights of each channel sum to 1, so a kernel never adds or removes light.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .profiles import TRUNCATION

KERNEL_TYPES = ("preintegrated", "artist")

#: (variance mm^2, weight) of the skin profile's Gaussians (d'Eon 2007 via Jimenez et al. 2015);
#: the narrowest term (0.233 at 0.0064) is left to the strength, as in the reference code.
SKIN_GAUSSIANS = ((0.0484, 0.100), (0.187, 0.118), (0.567, 0.113), (1.99, 0.358), (7.41, 0.078))
#: The reference demo's per-channel falloff and strength (docs/references.md §3).
DEMO_FALLOFF = (1.0, 0.37, 0.3)
DEMO_STRENGTH = (0.48, 0.41, 0.28)

#: Mean squared radius of the 2-D skin profile at falloff 1: 2 sum(w v) / sum(w), mm^2.
_SKIN_R2 = 2.0 * sum(v * w for v, w in SKIN_GAUSSIANS) / sum(w for _, w in SKIN_GAUSSIANS)
#: Mean squared radius of the 2-D Burley profile: 14 d^2 (integral of r^2 times its radial pdf).
_BURLEY_R2 = 14.0


@dataclass(frozen=True)
class SeparableKernel:
    """One 1-D kernel applied twice (horizontally, then vertically).

    ``offsets_su``: (n,) tap positions in scene units, ascending, symmetric about the centre tap.
    ``weights``: (n, 3) per-channel weights, each column summing to 1.
    """

    offsets_su: np.ndarray
    weights: np.ndarray
    kind: str = "custom"

    def __post_init__(self):
        o = np.asarray(self.offsets_su, dtype=np.float64)
        w = np.asarray(self.weights, dtype=np.float64)
        if o.ndim != 1 or o.size < 1 or not np.all(np.isfinite(o)):
            raise ValueError(f"offsets_su: expected a 1-D array of finite offsets, got shape {o.shape}")
        if w.shape != (o.size, 3):
            raise ValueError(f"weights: expected shape ({o.size}, 3), got {w.shape}")
        if not np.all(np.isfinite(w)):
            raise ValueError(f"weights: {int((~np.isfinite(w)).sum())} of {w.size} are not finite (NaN or Inf)")
        if np.any(np.diff(o) <= 0):
            raise ValueError("offsets_su: expected strictly ascending offsets")
        sums = w.sum(axis=0)
        if np.any(np.abs(sums - 1.0) > 1e-6):
            raise ValueError(f"weights: each channel must sum to 1, got {sums}")
        object.__setattr__(self, "offsets_su", o)
        object.__setattr__(self, "weights", w)

    def __len__(self) -> int:
        return int(self.offsets_su.size)

    @property
    def radius_su(self) -> float:
        return float(np.abs(self.offsets_su).max())

    def spread_su(self) -> np.ndarray:
        """Per-channel standard deviation of the 1-D kernel (scene units)."""
        return np.sqrt((self.weights * self.offsets_su[:, None] ** 2).sum(axis=0))

    def matrix(self, channel: int) -> np.ndarray:
        """The 2-D kernel the two passes apply for ``channel``: outer(w, w)."""
        w = self.weights[:, channel]
        return np.outer(w, w)


def check_taps(n_taps) -> int:
    if isinstance(n_taps, bool) or not isinstance(n_taps, (int, np.integer)) or n_taps < 1 or n_taps % 2 == 0:
        raise ValueError(f"n_taps: expected an odd integer >= 1 (e.g. 11, 17, 25), got {n_taps!r}")
    return int(n_taps)


def tap_offsets(n_taps: int, radius: float) -> np.ndarray:
    """Quadratically spaced offsets over [-radius, radius], denser near the centre (reference
    code: offset = range * sign(t) * t^2 for t evenly spaced in [-1, 1])."""
    n = check_taps(n_taps)
    if n == 1:
        return np.zeros(1)
    t = np.linspace(-1.0, 1.0, n)
    return radius * np.sign(t) * t * t


def footprints(offsets: np.ndarray) -> np.ndarray:
    """(n + 1,) edges of each tap's footprint: the midpoints between taps, the outer taps
    extended by half their gap."""
    o = np.asarray(offsets, dtype=np.float64)
    if o.size == 1:
        return np.array([-0.5, 0.5])
    mid = 0.5 * (o[1:] + o[:-1])
    return np.concatenate([[o[0] - (mid[0] - o[0])], mid, [o[-1] + (o[-1] - mid[-1])]])


def identity_kernel() -> SeparableKernel:
    return SeparableKernel(np.zeros(1), np.ones((1, 3)), "identity")


def artist_kernel(
    n_taps: int = 17,
    *,
    unit_su: float,
    falloff=DEMO_FALLOFF,
    strength=DEMO_STRENGTH,
    radius_su: float | None = None,
) -> SeparableKernel:
    """The reference code's artist-friendly kernel.

    ``unit_su``: scene units per millimetre of the skin profile (the reference demo's width).
    ``falloff`` (R, G, B) widens each channel's profile (r / (0.001 + falloff)); ``strength``
    (R, G, B) in [0, 1] blends the centre tap towards identity (0 = no scattering). Taps span
    +-2 mm (+-3 above 20 taps), as in the reference code; ``radius_su`` lays them over
    +-radius_su scene units instead (a kernel bounded by the object, ``core.scene.extent``), the
    profile still evaluated at its own width.
    """
    n = check_taps(n_taps)
    if not (np.isfinite(unit_su) and unit_su >= 0):
        raise ValueError(f"unit_su: expected a finite length >= 0, got {unit_su!r}")
    falloff = np.broadcast_to(np.asarray(falloff, dtype=np.float64), (3,))
    strength = np.broadcast_to(np.asarray(strength, dtype=np.float64), (3,))
    if np.any(~np.isfinite(falloff)) or np.any(falloff < 0):
        raise ValueError(f"falloff: expected three values >= 0, got {falloff!r}")
    if np.any(~np.isfinite(strength)) or np.any(strength < 0) or np.any(strength > 1):
        raise ValueError(f"strength: expected three values in [0, 1], got {strength!r}")
    if n == 1 or unit_su == 0:
        return identity_kernel()
    mm = tap_offsets(n, 3.0 if n > 20 else 2.0)
    if radius_su is not None and radius_su < mm.max() * unit_su:
        mm = mm * (float(radius_su) / (mm.max() * unit_su))
    edges = footprints(mm)
    area = np.diff(edges)
    rr = mm[:, None] / (0.001 + falloff[None, :])
    prof = sum(w * np.exp(-(rr * rr) / (2.0 * v)) / (2.0 * math.pi * v) for v, w in SKIN_GAUSSIANS)
    weights = prof * area[:, None]
    weights /= weights.sum(axis=0, keepdims=True)
    centre = n // 2
    weights *= strength[None, :]
    weights[centre] += 1.0 - strength
    return SeparableKernel(mm * unit_su, weights, "artist")


def artist_params_from_d(d_su) -> dict:
    """Artist-kernel parameters matching Burley profiles of shape ``d_su`` (R, G, B).

    A documented choice, calibrated by the comparison: the widest channel's mean squared radius
    matches Burley's (14 d^2) at full strength; the other channels' falloffs scale by d_c/d_max.
    """
    d = np.asarray(d_su, dtype=np.float64)
    dmax = float(d.max())
    if dmax <= 0:
        return {"unit_su": 0.0, "falloff": (1.0, 1.0, 1.0), "strength": (0.0, 0.0, 0.0)}
    return {
        "unit_su": dmax * math.sqrt(_BURLEY_R2 / _SKIN_R2),
        "falloff": tuple(float(v) for v in d / dmax),
        "strength": (1.0, 1.0, 1.0),
    }


def _gauss_nodes(m: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(m)
    return 0.5 * (x + 1.0), 0.5 * w


def _cell_integrals(edges: np.ndarray, d: float, sub: int = 12, *, relative: bool = False) -> np.ndarray:
    """(n, n) integrals of the area profile R(r) (unit albedo) over each footprint cell.

    Gauss-Legendre in each cell; the cell holding the pole at r = 0 is split four times towards
    it so that the 1/r singularity is integrated accurately (the rest of the cell is smooth).
    """
    n = edges.size - 1
    # ``relative`` leaves out the constant 1 / (8 pi d): for a kernel that is normalized
    # afterwards, where a very large d would make the products overflow or underflow.
    norm = 1.0 if relative else 8.0 * math.pi * d
    xs, ws = _gauss_nodes(sub)
    pts, wts = [], []
    for i in range(n):
        a, b = edges[i], edges[i + 1]
        if a < 0 < b:
            # Split at 0 and grade the pieces geometrically towards it.
            cuts = [a * 2.0**-k for k in range(0, 9)] + [0.0] + [b * 2.0**-k for k in range(8, -1, -1)]
            p, q = [], []
            for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):
                p.append(lo + (hi - lo) * xs)
                q.append((hi - lo) * ws)
            pts.append(np.concatenate(p))
            wts.append(np.concatenate(q))
        else:
            pts.append(a + (b - a) * xs)
            wts.append((b - a) * ws)
    out = np.empty((n, n))
    for i in range(n):
        x, wx = pts[i], wts[i]
        for j in range(i, n):
            y, wy = pts[j], wts[j]
            r = np.hypot(x[:, None], y[None, :])
            e3 = np.exp(-r / (3.0 * d))
            prof = (e3 * e3 * e3 + e3) / (r * norm)
            out[i, j] = out[j, i] = wx @ prof @ wy
    return out


PREINTEGRATION_METHODS = ("marginal", "rank1")


def preintegrated_kernel(
    n_taps: int = 17, *, d_su, radius_su: float | None = None, method: str = "marginal"
) -> SeparableKernel:
    """Kernel pre-integrated from the Burley profile of shape ``d_su`` (R, G, B, scene units).

    Taps span +-``radius_su`` (default 16 d of the widest channel, the truncation shared with
    Burley and Cycles). Per channel, the profile is integrated over every pair of footprints
    (an n x n matrix M); the 1-D kernel is then, normalized to sum 1:

    - ``marginal`` (default): the row sums of M, the profile integrated across the other axis.
      The two passes then reproduce the profile's line- and edge-spread exactly (what a shadow
      edge shows) and its energy;
    - ``rank1``: M's first singular vector, the k whose outer(k, k) is closest to M in the
      least-squares sense. It follows the profile's sharp peak and so spreads an edge less
      (the comparison's fidelity table measures both readings of the paper).

    A channel with d = 0 gets the identity (all weight on the centre).
    """
    if method not in PREINTEGRATION_METHODS:
        raise ValueError(f"method: {method!r} is not one of {', '.join(PREINTEGRATION_METHODS)}")
    n = check_taps(n_taps)
    d = np.broadcast_to(np.asarray(d_su, dtype=np.float64), (3,))
    if np.any(~np.isfinite(d)) or np.any(d < 0):
        raise ValueError(f"d_su: expected three finite lengths >= 0, got {d_su!r}")
    dmax = float(d.max())
    if n == 1 or dmax <= 0:
        return identity_kernel()
    radius = TRUNCATION * dmax if radius_su is None else float(radius_su)
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"radius_su: expected a finite length > 0, got {radius_su!r}")
    return _preintegrated(n, tuple(float(v) for v in d), radius, method)


@functools.lru_cache(maxsize=64)
def _preintegrated(n: int, d: tuple[float, float, float], radius: float, method: str) -> SeparableKernel:
    """The kernel itself, built once per parameter set: the integrals cost tens of milliseconds,
    and apply asks for the same kernel for every frame. Its arrays are read-only, as it is shared."""
    offsets = tap_offsets(n, radius)
    edges = footprints(offsets)
    weights = np.zeros((n, 3))
    centre = n // 2
    for c in range(3):
        # A profile far narrower than the central footprint is a delta at this sampling.
        if d[c] <= 0 or d[c] * TRUNCATION < 1e-3 * (edges[centre + 1] - edges[centre]):
            weights[centre, c] = 1.0
            continue
        m = _cell_integrals(edges, d[c], relative=True)
        k = m.sum(axis=1) if method == "marginal" else np.abs(np.linalg.svd(m)[0][:, 0])
        weights[:, c] = k / k.sum()
    kernel = SeparableKernel(offsets, weights, "preintegrated")
    kernel.offsets_su.setflags(write=False)
    kernel.weights.setflags(write=False)
    return kernel


def make_kernel(
    kernel_type: str, n_taps: int, *, d_su=None, radius_su: float | None = None, **artist
) -> SeparableKernel:
    """The kernel of ``kernel_type`` ("preintegrated" or "artist") for profile shape ``d_su``;
    artist parameters not given are derived from ``d_su`` (``artist_params_from_d``).
    ``radius_su`` bounds how far the taps reach (by default the kernel's own reach)."""
    if kernel_type not in KERNEL_TYPES:
        raise ValueError(f"unknown kernel type {kernel_type!r}; expected one of: {', '.join(KERNEL_TYPES)}")
    if kernel_type == "preintegrated":
        if d_su is None:
            raise ValueError("d_su: the pre-integrated kernel needs the profile's d per channel (scene units)")
        if radius_su is not None:
            d_max = float(np.max(_check_lengths(d_su)))
            radius_su = radius_su if radius_su < TRUNCATION * d_max else None
        return preintegrated_kernel(n_taps, d_su=d_su, radius_su=radius_su)
    params = artist_params_from_d(d_su) if d_su is not None else {}
    params.update({k: v for k, v in artist.items() if v is not None})
    if "unit_su" not in params:
        raise ValueError("unit_su: the artist kernel needs its width (scene units per mm of the profile) or d_su")
    return artist_kernel(n_taps, radius_su=radius_su, **params)


def _check_lengths(d_su) -> np.ndarray:
    d = np.broadcast_to(np.asarray(d_su, dtype=np.float64), (3,))
    if np.any(~np.isfinite(d)) or np.any(d < 0):
        raise ValueError(f"d_su: expected three finite lengths >= 0, got {d_su!r}")
    return d


def bounded(kernel: SeparableKernel, radius_su: float) -> SeparableKernel:
    """A given kernel laid over +-``radius_su`` when it reaches farther (its weights kept): the
    bound for a kernel that cannot be rebuilt from parameters (``core.scene.extent``)."""
    if kernel.radius_su <= radius_su or len(kernel) == 1:
        return kernel
    return SeparableKernel(kernel.offsets_su * (radius_su / kernel.radius_su), kernel.weights, kernel.kind)
