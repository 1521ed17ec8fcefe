"""Input checks and the block-parallel loop shared by the techniques (no Blender)."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

#: Depth at or beyond this is background (Cycles writes 1e10 there, docs/references.md §2).
BACKGROUND_DEPTH = 1e9


#: Where the albedo is applied around a scatter: after it, or half before and half after.
ALBEDO_MODES = ("post", "pre-post")


def check_albedo_mode(mode: str) -> str:
    if mode not in ALBEDO_MODES:
        raise ValueError(f"albedo_mode: {mode!r} is not one of {', '.join(ALBEDO_MODES)}")
    return mode


def split_albedo(albedo: np.ndarray, mode: str) -> tuple[np.ndarray | None, np.ndarray]:
    """(factor on the light before the scatter, factor after it) for ``mode``: "post" gives
    (1, A); "pre-post" gives (sqrt(A), sqrt(A)), keeping half of the texture detail under the
    blur (Jimenez et al. 2015's pre/post scatter option). The first is None for "post"."""
    if check_albedo_mode(mode) == "pre-post":
        root = np.sqrt(np.maximum(albedo, 0.0))
        return root, root
    return None, albedo


def image(x, name: str, channels: int | None = 3) -> np.ndarray:
    """``x`` as float32 (H, W, C) (or (H, W) when ``channels`` is None); ValueError otherwise.

    float16 and float64 inputs are converted (computing in half floats would overflow at 65504,
    docs/references.md §5); the caller's array is never written to.
    """
    a = np.asarray(x)
    if a.dtype.kind not in "fiub":
        raise ValueError(f"{name}: expected a numeric array, got dtype {a.dtype}")
    if channels is None:
        if a.ndim == 3 and a.shape[2] == 1:
            a = a[..., 0]
        if a.ndim != 2:
            raise ValueError(f"{name}: expected shape (H, W), got {a.shape}")
    else:
        if a.ndim != 3 or a.shape[2] < channels:
            raise ValueError(f"{name}: expected shape (H, W, {channels}), got {a.shape}")
        a = a[..., :channels]
    if a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"{name}: expected at least one pixel, got shape {a.shape}")
    return a.astype(np.float32, copy=False)


def vector_length(v: np.ndarray) -> np.ndarray:
    """The length of each vector of ``v`` (..., 3) along its last axis, keeping that axis (...,
    1): ``np.linalg.norm(v, axis=-1, keepdims=True)`` to the bit (the same products and the
    same sum, (x^2 + y^2) + z^2, then the square root) without its generic path, which took
    five times as long on the small arrays of ``core.pipeline.auto``'s features (26 against 5 us on
    50 x 37 blocks)."""
    s = v * v
    return np.sqrt(s[..., 0:1] + s[..., 1:2] + s[..., 2:3])


def same_size(shape: tuple[int, int], **arrays) -> None:
    for name, a in arrays.items():
        if a is not None and a.shape[:2] != shape:
            raise ValueError(f"{name}: shape {a.shape[:2]} does not match the image's {shape}")


def mask_array(mask, shape: tuple[int, int]) -> np.ndarray:
    """The pixels a technique runs on, as bool (H, W)."""
    if mask is None:
        raise ValueError("mask: expected a boolean (H, W) array of the pixels to process, got None")
    m = np.asarray(mask)
    if m.ndim == 3 and m.shape[2] == 1:
        m = m[..., 0]
    if m.shape != shape:
        raise ValueError(f"mask: expected shape {shape}, got {m.shape}")
    if m.dtype != bool:
        m = m > 0.5
    return m


def finite_pixels(*arrays: np.ndarray) -> np.ndarray:
    """True where every array is finite over all its channels (at least one array)."""
    ok: np.ndarray | None = None
    for a in arrays:
        f = np.isfinite(a)
        if f.ndim == 3:
            # Channel by channel: all(axis=2) over a short last axis is several times slower.
            g = f[..., 0].copy()
            for c in range(1, f.shape[2]):
                g &= f[..., c]
            f = g
        ok = f if ok is None else ok & f
    if ok is None:
        raise TypeError("finite_pixels: expected at least one array")
    return ok


def float32_factor(value: float) -> np.float32:
    """A Python number as the float32 that NumPy multiplies a float32 array by (+inf beyond
    float32's range: what ``value * array`` gives there on NumPy 2)."""
    with np.errstate(over="ignore"):
        return np.float32(value)


def positive_finite(value, name: str, *, allow_zero: bool = True) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name}: expected a finite number {'>=' if allow_zero else '>'} 0, got {value!r}")
    return v


def rgb_lengths(value, name: str) -> np.ndarray:
    """Three finite lengths >= 0 (one number is used for all three channels)."""
    if value is None:
        raise ValueError(f"{name}: expected three lengths (R, G, B) in scene units, got None")
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        a = np.repeat(a, 3)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ValueError(f"{name}: expected three finite lengths >= 0 (R, G, B), got {value!r}")
    return a


#: One pixel's three float32 channels as a single 12-byte item: gathering (N,) items is several
#: times faster than gathering N rows of a (HW, 3) array with 2-D fancy indexing.
RGB_ITEM = np.dtype((np.void, 12))
ZERO_RGB = np.zeros(3, np.float32).view(RGB_ITEM)[0]


def pixel_rows(a: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 as (H*W,) 12-byte items; a view when ``a`` is C-contiguous."""
    return np.ascontiguousarray(a, dtype=np.float32).reshape(-1, 3).view(RGB_ITEM).ravel()


def block_selection(idx: np.ndarray, start: int, stop: int):
    """``idx[start:stop]`` (sorted flat pixel indices) as a slice when they are consecutive."""
    first, last = int(idx[start]), int(idx[stop - 1])
    if last - first == stop - start - 1:
        return slice(first, last + 1)
    return idx[start:stop]


def as_rows(items: np.ndarray) -> np.ndarray:
    """(N,) 12-byte items (``pixel_rows``) as a float32 (N, 3) view."""
    return items.view(np.float32).reshape(-1, 3)


_WORKERS = max(1, min(4, os.cpu_count() or 1))
_POOL: ThreadPoolExecutor | None = None


def set_workers(n: int) -> None:
    """How many threads ``for_blocks`` runs the NumPy code's blocks on (at least 1; benchmarks
    compare 1 and 2). Takes effect for the next pool: an existing one is shut down."""
    global _WORKERS, _POOL
    if int(n) != n or n < 1:
        raise ValueError(f"workers: expected an integer >= 1, got {n!r}")
    _WORKERS = int(n)
    if _POOL is not None:
        _POOL.shutdown(wait=True)
        _POOL = None


def for_blocks(count: int, block: int, func) -> None:
    """Call ``func(start, stop)`` over [0, count) in blocks, on a few threads.

    NumPy releases the GIL in its array loops, so the blocks run in parallel; each block writes
    its own slice of the output, so no locking is needed. Small blocks also stay in the cache.
    """
    global _POOL
    starts = range(0, count, block)
    if count <= block or _WORKERS == 1:
        for s in starts:
            func(s, min(s + block, count))
        return
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=_WORKERS, thread_name_prefix="sss_lab")
    # list() re-raises the first error of any block.
    list(_POOL.map(lambda s: func(s, min(s + block, count)), starts))


def bounding_box(m: np.ndarray) -> tuple[slice, slice] | None:
    """The rows and columns that hold the pixels of the (H, W) bool array ``m`` (None when there
    are none)."""
    rows = np.flatnonzero(m.any(axis=1))
    if not rows.size:
        return None
    cols = np.flatnonzero(m.any(axis=0))
    return slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1)


def median(values: np.ndarray) -> float:
    """``float(np.median(values))`` of a 1-D float array without NaN (at least one value),
    reordering ``values`` in place (a copy the caller owns). One selection of the upper middle
    value, and the largest value below it, instead of ``np.median``'s selection of both middle
    values and of the largest value (where it looks for NaN): some eight times faster on a
    million values, and the same two middle values and the same mean of them (``np.median`` of
    the one or two)."""
    n = values.size
    k = n // 2
    values.partition(k)
    if n % 2:
        return float(np.median(values[k : k + 1]))
    return float(np.median(np.array([values[:k].max(), values[k]], values.dtype)))


def all_finite(a: np.ndarray) -> bool:
    """True when every value of ``a`` is finite, found without a bool frame of ``np.isfinite``.

    A NaN or an infinity among the values makes their float sum NaN or infinite (NaN and inf
    propagate through additions; inf + -inf is NaN), so a finite sum means every value is
    finite. Finite values whose sum overflows make it infinite too: then the values are tested
    one by one."""
    with np.errstate(over="ignore", invalid="ignore"):
        total = np.add.reduce(a, axis=None)
    return bool(np.isfinite(total)) or bool(np.isfinite(a).all())
