"""What every compiled (Numba) kernel shares: float32 constants, e^x, clipping, the compositing's
clamp, spans of a row, a pixel's scale, unit vectors; and the rules every kernel follows.

The compiled kernels: one fused loop per pixel, parallel over rows. Each owner keeps its kernels
beside its NumPy reference, in ``_kernels.py`` (``core/techniques/<name>/_kernels.py``, the shared
physics' in ``core/optics/_kernels.py``, the pipeline's in ``core/pipeline/_kernels.py``), on the
primitives of this module. They are imported only through ``core.compute.backend.kernels`` (which
sets the on-disk cache first); the technique functions validate their inputs, compute what every
backend shares (the pixels that take part, the footprint, the albedo split)
and hand the per-pixel work to these kernels or to their own NumPy code, the readable reference
(docs/references.md §11).

Each kernel places its taps and samples with the reference's float32 operations in the
reference's order, without fused multiply-add: tap and sample positions, indices and
comparisons come out bit-identical, so a sample never lands on another pixel. What differs: the
sums over a pixel's taps or samples are in another order (SSSS sums its taps one after the
other; Burley's sums over its samples are reassociated, ``fastmath={"reassoc"}`` on the
function that holds them and on nothing that places a sample, so that they vectorize; the
reference sums with BLAS matrix products, in its own order), a tap's two samples share one
multiplication by its weight, Burley's sums of products are fused multiply-adds (one rounding
where the reference has two), and e^x is ``fast_exp`` (within 1 unit in the last place; NumPy's is
within 4). The bound that follows is ``core.compute.backend.tolerance``; the tests run every technique
call of the core suite on both backends against it. Where the reference multiplies a sample by
a weight of exactly 0 (a pixel that takes no part: colour 0, depth key +inf), a kernel adds 0
(selects it away), which is the same. Burley's clean-up (``core.techniques.burley.technique._smooth``) sums in
float64 in the reference's order: the same result to the bit, from the same gathered values.

What SSSS and Burley share before their kernels (albedo x diffuse, the pixels that take part,
their footprint, their bounding box and extent) is one pass over the frame
(``prepare_pixels``); the kernels then visit only the bounding box of the pixels that take
part. Pixels are visited row by row (``prange`` over rows; SSSS's vertical pass over strips of
columns, Burley over tiles), each written by one thread only, and no kernel allocates anything
the size of a frame. Index arithmetic in the vectorized loops is 32-bit (frames
have fewer than 2^31 / 3 pixels), so that a 512-bit register holds 16 lanes (``core.compute.backend``
lets LLVM use them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

f32 = np.float32


ZERO = f32(0.0)


ONE = f32(1.0)


TINY = f32(1e-30)


INF = f32(np.inf)


EPS = f32(1e-6)  # core.techniques.sta.technique._EPS


R2_MIN = f32(1e-12)


QUARTER = f32(0.25)


THREE = f32(3.0)


TWO = f32(2.0)


def parallel_chunks(size: int):
    """Mark a kernel whose parallel loop is over larger work items than rows with their count per
    chunk (``core.compute.backend.run_kernel`` reads it; the others take ``ROWS_PER_CHUNK``):
    Burley's tiles and STA's groups of rows one per chunk, the energy's table reads entries."""

    def mark(fn):
        fn.parallel_chunks = size
        return fn

    return mark


#: Rows per work item of the parallel loops: small enough to balance the threads when the
#: mask covers only part of the frame, large enough to amortize scheduling.
ROWS_PER_CHUNK = 4


_LOG2E = f32(1.4426950408889634)


_LN2_HI = f32(0.693359375)  # 9 significant bits: k ln2_hi is exact for |k| < 2^15


_LN2_LO = f32(-2.12194440e-4)


_EXP_MIN = f32(-87.3)  # e^x below this is under float32's smallest normal number


_C2, _C3, _C4, _C5, _C6, _C7 = (f32(1.0 / math.factorial(i)) for i in range(2, 8))


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def fast_exp(x):
    """e^x in float32 for x <= 0, within 1 unit in the last place (measured 0.93 over 4 million
    x in [-87.2, 0] against float64; the C library's and NumPy's are within 1 and 4, NumPy's
    measured 2.44), as arithmetic that vectorizes: x = k ln 2 + r with |r| <= ln(2) / 2 (Cody
    and Waite's two-part ln 2), e^r by its Taylor polynomial to r^7 (truncation below 4e-9),
    2^k from the exponent bits; with fused multiply-adds (``fastmath`` "contract", here only:
    LLVM inlines it with its own flags), fewer roundings. 0 below -87.3 (the reference gives at
    most 1.2e-38 there)."""
    k = np.rint(x * _LOG2E)
    r = x - k * _LN2_HI
    r = r - k * _LN2_LO
    p = _C7 * r + _C6
    p = p * r + _C5
    p = p * r + _C4
    p = p * r + _C3
    p = p * r + _C2
    p = p * r + ONE
    p = p * r + ONE
    bits = (np.int32(k) + np.int32(127)) << np.int32(23)
    v = p * np.int32(bits).view(np.float32)
    return v if x >= _EXP_MIN else ZERO


@njit(cache=True, inline="always", error_model="numpy")
def add_kept_non_negative(i, o):
    """Compositing one channel: Combined ``i`` plus the SSS term ``o``, except that a sum that
    would turn a non-negative Combined negative is 0 and its term minus Combined
    (``core.pipeline.apply``'s clamp). Returns (term, sum, clamped). Selects, no branches: a loop
    that calls it still vectorizes; the same float32 sum as the NumPy code."""
    t = i + o
    n = (t < ZERO) & (i >= ZERO)
    return (-i if n else o), (ZERO if n else t), n


@njit(cache=True, inline="always", error_model="numpy")
def clip(v, hi):
    """min(max(v, 0), hi) as np.clip gives it; NaN gives 0 (an index must never be NaN)."""
    v = v if v > ZERO else ZERO
    return v if v < hi else hi


@njit(cache=True, inline="always", error_model="numpy")
def span(row):
    """(first, last + 1) of the True entries of a bool row; first >= last + 1 when there are none."""
    n = row.size
    x0 = 0
    while x0 < n and not row[x0]:
        x0 += 1
    x1 = n
    while x1 > x0 and not row[x1 - 1]:
        x1 -= 1
    return x0, x1


@njit(cache=True, inline="always", error_model="numpy")
def bytes_span(row):
    """``span`` of a bool row viewed as bytes (uint8), 32 entries at a time where they are all
    False (an OR of 32 bytes, which vectorizes), then one at a time: the same (first, last + 1)."""
    n = row.size
    x0 = 0
    while x0 + 32 <= n:
        acc = np.uint8(0)
        for k in range(32):
            acc |= row[x0 + k]
        if acc:
            break
        x0 += 32
    while x0 < n and not row[x0]:
        x0 += 1
    x1 = n
    while x1 - 32 >= x0:
        acc = np.uint8(0)
        for k in range(32):
            acc |= row[x1 - 32 + k]
        if acc:
            break
        x1 -= 32
    while x1 > x0 and not row[x1 - 1]:
        x1 -= 1
    return x0, x1


BACKGROUND = f32(1e9)  # core.base.arrays.BACKGROUND_DEPTH, exactly a float32


@njit(cache=True, inline="always", error_model="numpy")
def scale_of(z, cam):
    """A pixel's ``core.scene.scene.Camera.pixels_per_unit`` at depth ``z`` (finite, > 0: a pixel that
    takes part), float32 as NumPy computes it; ``cam`` = (1 for orthographic else 0, the
    orthographic pixels per unit or the focal length in pixels). The kernels compute it where
    they need it instead of reading a frame of it."""
    return cam[1] if cam[0] != ZERO else cam[1] / z


@njit(cache=True, inline="always", error_model="numpy")
def normalize3(x, y, z):
    """(x, y, z, |v|) normalized as core.optics.lights.norm does it."""
    length = x * x
    length += y * y
    length += z * z
    length = math.sqrt(length)
    inv = ONE / (length if length > TINY else TINY)
    return x * inv, y * inv, z * inv, length


u64 = np.uint64


@njit(cache=True, inline="always", error_model="numpy")
def nan_to_num64(v):
    """np.nan_to_num of a float64: NaN 0, infinities the largest finite numbers."""
    if v != v:
        return 0.0
    if v == np.inf:
        return 1.7976931348623157e308
    if v == -np.inf:
        return -1.7976931348623157e308
    return v


_F32_MAX = f32(3.4028234663852886e38)


@njit(cache=True, inline="always", error_model="numpy")
def nan_to_num32(v):
    """np.nan_to_num of a float32."""
    if v != v:
        return ZERO
    if v == INF:
        return _F32_MAX
    if v == -INF:
        return -_F32_MAX
    return v


@njit(cache=True, inline="always", error_model="numpy")
def norm3(a, b, c):
    """np.linalg.norm of a float32 (..., 3) along its last axis: sqrt((a^2 + b^2) + c^2)."""
    return np.sqrt(a * a + b * b + c * c)
