"""How many of the spiral's samples each pixel of Burley's gather takes (``adaptive=True``).

After Xie, Olano, Karis and Narkowicz's variance-guided sampling (docs/references.md §21): a
pixel needs few samples where the profile covers few pixels, or where the light under it hardly
varies (the estimator is a weighted mean of that light, self-normalized: under a uniform light
one sample gives the exact result), and its full count at a shadow edge. Their variance comes
from the previous frames; a single frame has none, so here it is the light's own spread under
the footprint, measured on the frame:

- footprint: F = s x min(16 d_max, the object's extent) pixels (s: the pixel's pixels per scene
  unit; the spiral's reach). The pixel takes at most ceil(F^2) samples (at 32, below), about
  one per pixel of the footprint's square: 1 at F = 1 px, 4 at 2 px, 9 at 3 px; from 5.7 px on
  it is no limit at 32 samples. (Fewer per pixel would not do: the estimator's variance falls
  as 1 / n whatever the footprint, and an edge 3 px away still moves a pixel whose footprint is
  6 px.)
- variation: per block of ``BLOCK_PX`` x ``BLOCK_PX`` pixels, the light's mean mu_c and variance
  per channel over the gathered pixels within the footprint of the block's nearest pixel
  (``WINDOW`` x F), from summed-area tables of the blocks' sums. Of that variance, the part a
  plane fitted to the window's light explains counts ``GRADIENT`` times less than the rest (the
  golden-angle spiral surrounds its pixel, so a light that varies linearly across the footprint
  largely cancels: ``GRADIENT``). The estimator's relative standard error with n samples is
  about sqrt(variance) / (mu sqrt n), so the pixel takes at most ceil(max_c variance_c / mu_c^2 /
  ``ERROR``^2) samples (at 32, below; mu_c at least ``DARK`` times the channel's mean over the
  frame).
- the count is the smaller of the two, rounded up to the next count of the ladder (``ladder``:
  the maximum ``n_samples`` and its halvings by sqrt 2, down to 1): each count has its own
  stratified spiral (``spiral_su``), the same for every backend.

Both limits are those of 32 samples (``REFERENCE_SAMPLES``, Burley's default), where ``ERROR``
was measured to give the fixed 32 samples' quality. ``n_samples`` is the quality asked for:
with n the plan aims at what n fixed samples reach, a relative error of ``ERROR`` x sqrt(32 / n)
(a count's variance falls as 1 / count), and the footprint's limit grows likewise to
ceil(F^2 n / 32): each pixel takes n / 32 times the samples it would at 32, up to n. So 4096
samples converge as the fixed 4096 do instead of stopping where 32 samples' limits do (on a
small object far inside the profile the footprint's alone held every pixel to 182 samples, 0.11
off the limit the fixed spiral reaches within 0.0045: docs/references.md §21), and 8 take what
8 fixed samples are worth.

Both backends read the same plan (``plan``): the blocks' sums are the same to the bit
(``block_sums``) and the rest is NumPy on the blocks; the compiled kernel finds each pixel's
count from its footprint and its block's level with the reference's float64 comparisons, so the
two take the same samples at every pixel. The plan depends on the inputs only (no seed, no
thread count).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...compute import backend
from ...optics.profiles import TRUNCATION

#: The side of the blocks the light's variation is measured on (pixels).
BLOCK_PX = 8
#: Target relative standard error of a pixel's gathered light (module docstring). Measured on a
#: slanted shadow edge (tests/core/test_burley_adaptive.py's images, footprints 6 to 150 px): at
#: 0.05 the adaptive result is as far from a 1024-sample one as the fixed 32 samples' result
#: (docs/references.md §21).
ERROR = 0.05
#: The ``n_samples`` ``ERROR`` was measured at (Burley's default): a user's ``n_samples`` asks for
#: the quality of that many fixed samples, so the target is ``ERROR`` x sqrt(32 / ``n_samples``).
REFERENCE_SAMPLES = 32
#: A channel's mean below this share of its mean over the gathered pixels counts as this share:
#: the relative variation of a light near 0 is not that of its noise.
DARK = 1e-3
#: The window of the variation, as a share of the footprint: all of it, because a dark pixel
#: 8 d from a lit area twenty times brighter still takes about half of its light from the
#: profile's last 5 % (beyond 8 d), which a window of half the footprint would not see.
WINDOW = 1.0
#: How much less a linear variation of the light costs than the same variance otherwise: the box
#: variance of a plane over the footprint is about 4 times its variance under the profile (F^2 / 3
#: against 21 d^2 = 0.082 F^2 per axis), and the spiral's even angles cancel a further factor of
#: 30 (measured on a ramp at a 30 px footprint: relative error 0.0057 at 8 samples where
#: independent samples would give 0.032); 16 keeps a margin of 7.
GRADIENT = 16.0


class Plan(NamedTuple):
    """The samples each pixel takes: ``counts`` (L,) the ladder's counts, ascending (one count,
    ``n_samples``, when not adaptive); ``limit`` (L,) float64, the largest F^2 each count serves
    (a pixel of footprint F px takes at most the first count with F^2 <= limit: the counts times
    32 / ``n_samples``); ``blocks`` (Hb, Wb) int32 the level each
    block's variation allows (index into ``counts``), and ``block`` its side in pixels (a block of
    the frame's size when not adaptive)."""

    counts: np.ndarray
    limit: np.ndarray
    blocks: np.ndarray
    block: int

    def levels(self, flat_idx: np.ndarray, footprint_px: np.ndarray, width: int) -> np.ndarray:
        """The level (index into ``counts``) of the pixels of flat index ``flat_idx`` (frame
        width ``width``) whose footprint is ``footprint_px`` (float64)."""
        top = self.counts.size - 1
        by_footprint = np.minimum(np.searchsorted(self.limit, footprint_px * footprint_px, side="left"), top)
        y, x = np.divmod(flat_idx, width)
        return np.minimum(by_footprint, self.blocks[y // self.block, x // self.block]).astype(np.int32)


def ladder(n_max: int) -> np.ndarray:
    """The counts a pixel may take, ascending int32: ``n_max``, then ceil(n_max 2^(-k/2)) for
    k = 1, 2, ... down to 1 (32: 1, 2, 3, 4, 6, 8, 12, 16, 23, 32)."""
    counts = {int(n_max), 1}
    k = 1
    while True:
        v = math.ceil(n_max * 2.0 ** (-k / 2.0))
        counts.add(v)
        if v <= 1:
            break
        k += 1
    return np.array(sorted(counts), np.int32)


def fixed(n_samples: int) -> Plan:
    """Every pixel takes ``n_samples``."""
    counts = np.array([n_samples], np.int32)
    return Plan(counts, counts.astype(np.float64), np.zeros((1, 1), np.int32), 1 << 30)


def plan(light, ok, depth, camera, reach_su: float, n_samples: int) -> Plan:
    """The adaptive plan of a frame: ``light`` (H, W, 3) the light the gather reads, ``ok`` (H, W)
    the pixels it gathers, ``depth`` and ``camera`` their scale, ``reach_su`` 16 d_max (scene
    units), ``n_samples`` the most a pixel takes and the quality asked for (its relative error
    target ``ERROR`` x sqrt(32 / ``n_samples``), its footprint limit ``limit`` the counts times
    32 / ``n_samples``: module docstring)."""
    counts = ladder(n_samples)
    # The quality of n_samples fixed samples: both limits ask for n_samples / 32 times the samples
    # they ask for at 32 (module docstring); at 32 the factors are 1 exactly.
    limit = counts.astype(np.float64) * (REFERENCE_SAMPLES / n_samples)
    b = BLOCK_PX
    h, w = ok.shape
    hb, wb = -(-h // b), -(-w // b)
    blocks = np.zeros((hb, wb), np.int32)
    rows = np.flatnonzero(ok.any(axis=1))
    if counts.size == 1 or not rows.size:
        return Plan(counts, limit, blocks, b)
    cols = np.flatnonzero(ok.any(axis=0))
    # The blocks over the gathered pixels' box (the frame's block grid, padded with pixels that
    # take no part).
    by0, by1 = rows[0] // b, rows[-1] // b + 1
    bx0, bx1 = cols[0] // b, cols[-1] // b + 1
    ny, nx = by1 - by0, bx1 - bx0
    s1, s2, n, nearest = block_sums(light, ok, depth, by0 * b, bx0 * b, b, (ny, nx))
    with np.errstate(over="ignore", invalid="ignore"):
        scale = camera.pixels_per_unit(np.where(np.isfinite(nearest), nearest, np.float32(1.0)))
        window_px = WINDOW * reach_su * scale.astype(np.float64)
    radius = np.clip(np.ceil(np.nan_to_num(window_px / b, posinf=float(max(ny, nx)))), 1, max(ny, nx)).astype(np.intp)
    var, mean = _variation(s1, s2, n, radius)
    total = s1.sum(axis=(0, 1)) / max(float(n.sum()), 1.0)
    floor = np.maximum(DARK * np.abs(total), 1e-30)
    relative = (var / np.maximum(mean * mean, floor * floor)).max(axis=2)
    target = ERROR * math.sqrt(REFERENCE_SAMPLES / n_samples)
    need = relative / (target * target)
    level = np.minimum(np.searchsorted(counts.astype(np.float64), need, side="left"), counts.size - 1)
    blocks[by0:by1, bx0:bx1] = np.where(n > 0, level, 0)
    return Plan(counts, limit, blocks, b)


def _variation(s1, s2, n, radius):
    """(variance, mean) per block and channel of the light over its window (the blocks within
    ``radius``): of the variance, the part a plane through the
    window's light does not explain, plus that plane's part over ``GRADIENT`` (the spiral's
    samples surround the pixel: a light that varies linearly across the footprint costs a few
    samples little, module docstring). Blocks stand at their centres for the plane's fit."""
    ny, nx = n.shape
    iy, ix = np.mgrid[0:ny, 0:nx].astype(np.float64)
    # Summed-area tables of the moments the fit needs, one row and column of zeros first.
    parts = {
        "n": n, "nx": n * ix, "ny": n * iy, "nxx": n * ix * ix, "nyy": n * iy * iy, "nxy": n * ix * iy,
        "t": s1, "tx": s1 * ix[..., None], "ty": s1 * iy[..., None], "q": s2,
    }  # fmt: skip
    y0, y1 = np.clip(iy - radius, 0, ny).astype(np.intp), np.clip(iy + radius + 1, 0, ny).astype(np.intp)
    x0, x1 = np.clip(ix - radius, 0, nx).astype(np.intp), np.clip(ix + radius + 1, 0, nx).astype(np.intp)
    win = {}
    for key, v in parts.items():
        t = np.pad(v, ((1, 0), (1, 0)) + ((0, 0),) * (v.ndim - 2)).cumsum(0).cumsum(1)
        win[key] = t[y1, x1] - t[y0, x1] - t[y1, x0] + t[y0, x0]
    # Moments about the window's own block (ix, iy): small numbers, no cancellation.
    cnt = win["n"]
    sx = win["nx"] - ix * cnt
    sy = win["ny"] - iy * cnt
    sxx = win["nxx"] - 2.0 * ix * win["nx"] + ix * ix * cnt
    syy = win["nyy"] - 2.0 * iy * win["ny"] + iy * iy * cnt
    sxy = win["nxy"] - ix * win["ny"] - iy * win["nx"] + ix * iy * cnt
    t = win["t"]
    tx = win["tx"] - ix[..., None] * t
    ty = win["ty"] - iy[..., None] * t
    safe = np.maximum(cnt, 1.0)
    # The plane's slopes from the moments about the window's mean position (2 x 2 normal
    # equations, with a tiny ridge where the window holds one row or column of blocks).
    mx, my = sx / safe, sy / safe
    cxx = sxx - mx * sx + 1e-9 * safe
    cyy = syy - my * sy + 1e-9 * safe
    cxy = sxy - mx * sy
    det = cxx * cyy - cxy * cxy
    mean = t / safe[..., None]
    vx = tx - mx[..., None] * t  # covariance sums of the light with x and y
    vy = ty - my[..., None] * t
    bx = (cyy[..., None] * vx - cxy[..., None] * vy) / det[..., None]
    by = (cxx[..., None] * vy - cxy[..., None] * vx) / det[..., None]
    plane = np.maximum(bx * vx + by * vy, 0.0) / safe[..., None]  # the variance the plane explains
    total = np.maximum(win["q"] / safe[..., None] - mean * mean, 0.0)
    rest = np.maximum(total - plane, 0.0)
    return rest + np.minimum(plane, total) / GRADIENT, mean


def block_sums(light, ok, depth, y0: int, x0: int, b: int, shape: tuple[int, int]):
    """(s1, s2, n, nearest): per block of ``b`` x ``b`` pixels from frame row ``y0`` and column
    ``x0`` (``shape`` blocks), the float64 sums of the light (H, W, 3) and of its squares per
    channel over the pixels of ``ok``, their number and their least depth (float32, +inf for
    none). The pixels are summed one position of the block at a time (row, then column): the
    order of the compiled backend's ``burley_block_sums``, which gives the same sums to the bit
    (so both backends take the same samples)."""
    if backend.active() != "numpy":
        c = np.ascontiguousarray
        s1 = np.empty(shape + (3,), np.float64)
        s2 = np.empty(shape + (3,), np.float64)
        n = np.empty(shape, np.float64)
        nearest = np.empty(shape, np.float32)
        args = (c(light, dtype=np.float32), c(ok), c(depth, dtype=np.float32), y0, x0, b, s1, s2, n, nearest)
        backend.run_kernel(backend.kernels(__package__).burley_block_sums, *args)
        return s1, s2, n, nearest
    ny, nx = shape
    h, w = ok.shape
    s1 = np.zeros(shape + (3,), np.float64)
    s2 = np.zeros(shape + (3,), np.float64)
    n = np.zeros(shape, np.float64)
    nearest = np.full(shape, np.inf, np.float32)
    for dy in range(b):
        for dx in range(b):
            # The pixel at (dy, dx) of each block; blocks past the frame's edge read none.
            ys = np.arange(ny) * b + y0 + dy
            xs = np.arange(nx) * b + x0 + dx
            iny, inx = ys < h, xs < w
            on = np.zeros(shape, bool)
            on[np.ix_(iny, inx)] = ok[np.ix_(ys[iny], xs[inx])]
            v = np.zeros(shape + (3,), np.float64)
            v[np.ix_(iny, inx)] = np.asarray(light, np.float32)[np.ix_(ys[iny], xs[inx])]
            v[~on] = 0.0
            s1 += v
            s2 += v * v
            n += on
            z = np.full(shape, np.inf, np.float32)
            z[np.ix_(iny, inx)] = np.asarray(depth, np.float32)[np.ix_(ys[iny], xs[inx])]
            np.minimum(nearest, np.where(on, z, np.float32(np.inf)), out=nearest)
    return s1, s2, n, nearest


def footprint_reach(d_max: float, extent_su: float) -> float:
    """The spiral's reach in scene units (16 d_max, or the object's extent when smaller): a
    pixel's footprint is its scale times this."""
    return min(TRUNCATION * d_max, extent_su)
