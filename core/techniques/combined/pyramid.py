"""The spread pyramid of the light from behind: the blur levels, their box filters (three boxes per
axis, an approximate Gaussian), and the reduced grids that levels of ``SPREAD_COARSE_FROM_PX`` and
wider are blurred on (block sums, boxes of ``coarse_radii``, bilinear read back). The combined
technique's reference (``spread_back_light``) and its compiled light from behind share the layout."""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "SPREAD_COARSE_FROM_PX",
    "SPREAD_LEVELS_PX",
    "SPREAD_REDUCED_PX",
    "block_sums",
    "blur",
    "box_radius",
    "box_sum",
    "coarse_radii",
    "full_levels",
    "pyramid_layout",
    "read_back",
    "spread_factor",
    "spread_levels",
]


def box_sum(a: np.ndarray, radius: int, axis: int) -> np.ndarray:
    """Sum over a window of 2 radius + 1 along ``axis`` (zero outside), by cumulative sums."""
    pad = [(0, 0)] * a.ndim
    pad[axis] = (radius + 1, radius)
    c = np.cumsum(np.pad(a, pad), axis=axis, dtype=np.float64)
    n = a.shape[axis]
    hi = np.take(c, np.arange(2 * radius + 1, 2 * radius + 1 + n), axis=axis)
    lo = np.take(c, np.arange(0, n), axis=axis)
    return (hi - lo).astype(np.float32)


def box_radius(sigma_px: float) -> int:
    """Half-width r of the boxes ``blur`` uses for ``sigma_px``."""
    return max(1, int(round((math.sqrt(4.0 * sigma_px * sigma_px + 1.0) - 1.0) / 2.0)))


def blur(a: np.ndarray, sigma_px: float) -> np.ndarray:
    """Three box filters per axis, whose variance is sigma_px^2 (an approximate Gaussian; the width
    2 r + 1 of each box satisfies 3 ((2 r + 1)^2 - 1) / 12 = sigma^2 to the nearest integer r)."""
    r = box_radius(sigma_px)
    for axis in (0, 1):
        for _ in range(3):
            a = box_sum(a, r, axis)
    return a


#: Blur widths (px) the light from behind is spread at; a pixel's width is interpolated between two.
SPREAD_LEVELS_PX = tuple(0.5 * 2.0**k for k in range(1, 9))

#: The first width blurred on a reduced grid (a pyramid): a level of width sigma >= this is blurred
#: on the box's f x f block sums, f = sigma / ``SPREAD_REDUCED_PX``, so each level costs a quarter
#: of the one below it and the cost per pixel no longer grows with the widest width.
SPREAD_COARSE_FROM_PX = 16.0

#: The width (reduced pixels) a reduced level is blurred at: 8, where three boxes of half-width
#: 7 or 8 mixed (``coarse_radii``) come within 2 % of it (the full-resolution level 8 px's three
#: equal boxes are 6 % wide). At 4 the blocks would be twice as wide for the same boxes' error,
#: but the read back's spread, which varies across a block, would be 4 times the share.
SPREAD_REDUCED_PX = 8.0


def spread_factor(sigma_px: float) -> int:
    """The block size f (a power of two) ``spread_back_light`` blurs the level ``sigma_px`` at: 1
    below ``SPREAD_COARSE_FROM_PX``, else ``sigma_px`` / ``SPREAD_REDUCED_PX``."""
    if sigma_px < SPREAD_COARSE_FROM_PX:
        return 1
    return int(sigma_px / SPREAD_REDUCED_PX)


def coarse_radii(sigma_px: float, f: int) -> tuple[int, ...]:
    """Half-widths of the three boxes (per axis, reduced pixels) that blur the level ``sigma_px``
    on blocks of f x f: their variance sum_i r_i (r_i + 1) / 3 the nearest, with each r_i r or
    r + 1, to sigma_px^2 / f^2 - 1 / 4. The 1 / 4 (f^2 / 4 in pixels) is what the blocks
    ((f^2 - 1) / 12: a box of f) and the bilinear read back ((2 f^2 + 1) / 12: the two-point
    spread t (1 - t) f^2 averaged over a block's f phases) add, so the total stays sigma_px^2."""
    var = sigma_px * sigma_px / (f * f) - 0.25
    r = max(1, int(math.floor((math.sqrt(4.0 * var + 1.0) - 1.0) / 2.0)))
    best = min(range(4), key=lambda n: abs((n * (r + 1) * (r + 2) + (3 - n) * r * (r + 1)) / 3.0 - var))
    return (r,) * (3 - best) + (r + 1,) * best


def block_sums(a: np.ndarray) -> np.ndarray:
    """float64 sums of ``a``'s (H, W, P) 2 x 2 blocks from its origin (zeros beyond an odd edge):
    (a00 + a01) + (a10 + a11), shape (ceil(H / 2), ceil(W / 2), P)."""
    h, w = a.shape[:2]
    a = np.pad(a.astype(np.float64, copy=False), ((0, h % 2), (0, w % 2), (0, 0)))
    rows = a[:, 0::2] + a[:, 1::2]
    return rows[0::2] + rows[1::2]


def read_back(c: np.ndarray, f: int, h: int, w: int) -> np.ndarray:
    """float64 (h, w, P): the reduced grid ``c`` (float32 (Hc, Wc, P), blocks of f x f from the
    origin) read at each pixel's centre by bilinear interpolation between the blocks' centres
    (clamped at the edges): between two rows first, then along the row."""

    def axis(n: int, nc: int):
        u = np.clip((np.arange(n) + 0.5) / f - 0.5, 0.0, nc - 1.0)
        i0 = np.minimum(np.floor(u).astype(np.int64), max(nc - 2, 0))
        return i0, np.minimum(i0 + 1, nc - 1), u - i0

    y0, y1, ty = axis(h, c.shape[0])
    x0, x1, tx = axis(w, c.shape[1])
    ty = ty[:, None, None]
    rows = (1.0 - ty) * c[y0] + ty * c[y1]
    tx = tx[None, :, None]
    return (1.0 - tx) * rows[:, x0] + tx * rows[:, x1]


def spread_levels(top: float) -> list[float]:
    """The widths of the levels ``spread_back_light`` blurs at for a largest width ``top`` (0 first:
    the light itself), up to the first that reaches ``top``."""
    sigmas = [0.0]
    for sg in SPREAD_LEVELS_PX:
        if sigmas[-1] >= top:
            break
        sigmas.append(sg)
    return sigmas


def full_levels(sigmas: list[float]) -> int:
    """How many of the levels ``sigmas`` (0 first) are blurred at full resolution."""
    return sum(1 for sg in sigmas if spread_factor(sg) == 1)


def pyramid_layout(sigmas, box, wanted) -> tuple[np.ndarray, int]:
    """Where ``_reduced_levels`` puts the reduced levels of ``sigmas`` (the levels from
    ``full_levels``) in one float32 buffer: per level (block size f, or 0 where ``wanted[k]`` is
    False (None: every level wanted), offset, rows, columns), (levels, 4) int64, and the
    buffer's size. Each grid is (4, rows, columns): R, G, B and the mask, blocks of f x f from
    ``box``'s origin."""
    n_full = full_levels(sigmas)
    levels = np.zeros((len(sigmas) - n_full, 4), np.int64)
    size = 0
    for k in range(n_full, len(sigmas)):
        f = spread_factor(sigmas[k])
        hc, wc = -(-(box[1] - box[0]) // f), -(-(box[3] - box[2]) // f)
        on = wanted is None or bool(wanted[k])
        levels[k - n_full] = (f if on else 0, size, hc, wc)
        size += 4 * hc * wc if on else 0
    return levels, size
