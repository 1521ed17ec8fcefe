"""Compiled (Numba) kernels of the pipeline: compositing a technique's result, and ``auto``'s
features (block means, blurred change, the material's window)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..compute.jit import ZERO, add_kept_non_negative, f32


@njit(cache=True, parallel=True, error_model="numpy")
def composite(result, gain, albedo, diffuse, held, zeroed, mask, image, sss, overflow, negative):
    """``core.pipeline.apply``'s compositing of one material, equal to the bit to its NumPy code: on each
    pixel of ``mask`` (H, W) the technique's ``result`` (H, W, 3) times ``gain`` (3,), and where
    all three are finite the SSS term, that minus ``albedo`` x ``diffuse`` where ``held`` (0 in
    the channels ``zeroed``), written into ``sss`` (H, W, 3) and added to ``image`` (H, W, C);
    ``overflow[y]`` counts row y's pixels of ``mask`` whose result is not finite. A channel whose sum
    would turn a non-negative Combined negative is set to 0 (its SSS term to minus Combined):
    ``negative[y]`` counts row y's pixels where that happened. The same float32 products,
    differences and sums as the NumPy code (no fused multiply-add)."""
    h, w = mask.shape
    for y in prange(h):
        bad = 0
        clamped = 0
        for x in range(w):
            if not mask[y, x]:
                continue
            o0 = result[y, x, 0] * gain[0]
            o1 = result[y, x, 1] * gain[1]
            o2 = result[y, x, 2] * gain[2]
            if not (np.isfinite(o0) and np.isfinite(o1) and np.isfinite(o2)):
                bad += 1
                continue
            if held:
                o0 = o0 - albedo[y, x, 0] * diffuse[y, x, 0]
                o1 = o1 - albedo[y, x, 1] * diffuse[y, x, 1]
                o2 = o2 - albedo[y, x, 2] * diffuse[y, x, 2]
            if zeroed[0]:
                o0 = ZERO
            if zeroed[1]:
                o1 = ZERO
            if zeroed[2]:
                o2 = ZERO
            o0, t0, n0 = add_kept_non_negative(image[y, x, 0], o0)
            o1, t1, n1 = add_kept_non_negative(image[y, x, 1], o1)
            o2, t2, n2 = add_kept_non_negative(image[y, x, 2], o2)
            clamped += n0 | n1 | n2
            sss[y, x, 0] = o0
            sss[y, x, 1] = o1
            sss[y, x, 2] = o2
            image[y, x, 0] = t0
            image[y, x, 1] = t1
            image[y, x, 2] = t2
        overflow[y] = bad
        negative[y] = clamped


@njit(cache=True, error_model="numpy")
def block_means(a, size, part, count, out):
    """``core.pipeline.auto._block_means`` of ``a`` (h, w, C): per ``size`` x ``size`` block and channel the
    mean of its pixels at ``part // 2 + i part`` (rows and columns; ``count`` of them) as float32,
    non-finite values read as 0, summed in float64 a column of the sample at a time, as the
    reference sums them. Written into ``out`` (h // size, w // size, C) float32."""
    nby, nbx, nc = out.shape
    first = part // 2
    for by in range(nby):
        for bx in range(nbx):
            for c in range(nc):
                total = 0.0
                for dx in range(first, size, part):
                    column = 0.0
                    for dy in range(first, size, part):
                        v = f32(a[by * size + dy, bx * size + dx, c])
                        if np.isfinite(v):
                            column += np.float64(v)
                    total += column
                out[by, bx, c] = f32(total / count)


@njit(cache=True, error_model="numpy")
def blurred_change(e, mask, half, out):
    """``core.pipeline.auto``'s diffusion term of one channel: the mean of ``e`` (H, W) float32 over the
    pixels of ``mask`` in the box of half-width ``half`` around each pixel (clipped at the borders;
    ``e`` itself where the box holds none of them), minus ``e``, as float32 into ``out`` (H, W).
    ``_blurred``'s summed-area tables to the bit: the masked values' in float32 (NumPy's cumulative
    sums of a float32 array, down each column, then along each row), the mask's in float64, and
    each box's sum as the same four table reads in the same order."""
    h, w = e.shape
    num = np.zeros((h + 1, w + 1), np.float32)
    den = np.zeros((h + 1, w + 1), np.float64)
    for x in range(w):
        acc = ZERO
        accd = 0.0
        for y in range(h):
            acc += e[y, x] if mask[y, x] else ZERO
            accd += 1.0 if mask[y, x] else 0.0
            num[y + 1, x + 1] = acc
            den[y + 1, x + 1] = accd
    for y in range(1, h + 1):
        acc = ZERO
        accd = 0.0
        for x in range(1, w + 1):
            acc += num[y, x]
            accd += den[y, x]
            num[y, x] = acc
            den[y, x] = accd
    for y in range(h):
        y0 = min(max(y - half, 0), h)
        y1 = min(max(y + half + 1, 0), h)
        for x in range(w):
            x0 = min(max(x - half, 0), w)
            x1 = min(max(x + half + 1, 0), w)
            s = np.float64(num[y1, x1]) - np.float64(num[y0, x1]) - np.float64(num[y1, x0]) + np.float64(num[y0, x0])
            d = den[y1, x1] - den[y0, x1] - den[y1, x0] + den[y0, x0]
            v = np.float64(e[y, x])
            mean = s / max(d, 1e-300) if d > 0 else v
            out[y, x] = f32(mean - v)


@njit(cache=True, error_model="numpy")
def index_box(raw, k, box):
    """The pixels of Material Index ``k`` (0 <= k < 2^24, exact in float32) in ``raw`` (H, W)
    float32: those whose value rounds to ``k`` (``np.rint``; NaN and infinities round to no index).
    ``box`` (4,) int64: first row, last row + 1, first column, last column + 1 (all 0 when there
    is none)."""
    h, w = raw.shape
    target = f32(k)
    columns = np.zeros(w, np.bool_)
    r0, r1 = h, -1
    for y in range(h):
        found = False
        row = raw[y]
        for x in range(w):
            on = np.rint(row[x]) == target
            columns[x] |= on
            found |= on
        if found:
            r0 = min(r0, y)
            r1 = y
    box[0] = box[1] = box[2] = box[3] = 0
    if r1 >= 0:
        c0, c1 = w, 0
        for x in range(w):
            if columns[x]:
                c0 = min(c0, x)
                c1 = x + 1
        box[0], box[1], box[2], box[3] = r0, r1 + 1, c0, c1


@njit(cache=True, error_model="numpy")
def index_window(raw, k, seen, y0, x0, mask):
    """``mask`` (h, w) bool: on the window at (``y0``, ``x0``) the pixels of Material Index ``k``
    (as ``index_box``) whose three ``seen`` values (H, W, >= 3) are finite."""
    h, w = mask.shape
    target = f32(k)
    for i in range(h):
        row = raw[y0 + i, x0 : x0 + w]
        rgb = seen[y0 + i, x0 : x0 + w]
        out = mask[i]
        for j in range(w):
            finite = np.isfinite(rgb[j, 0]) & np.isfinite(rgb[j, 1]) & np.isfinite(rgb[j, 2])
            out[j] = finite & (np.rint(row[j]) == target)
