"""Compiled (Numba) kernels of the spread of the light from behind: the blur levels at full
resolution and on the reduced grids of the pyramid (``pyramid.py``)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ...compute.jit import ONE, ZERO, f32
from ...optics._kernels import SPREAD_STRIP
from ._kernels import PART_STRIP


@njit(cache=True, inline="always", error_model="numpy")
def _frame_level(mask, sigma, grid, k, y, x, c, cur, prev, out):
    """``spread_light``'s step at level ``k`` for pixel (``y``, ``x``) and channel ``c`` of the
    level's value ``cur``: where the pixel is on the mask and its width's upper level (the
    reference's searchsorted, clipped to 1.. the last) is ``k``, ``out`` = (1 - w) ``prev`` + w
    ``cur``; then ``prev`` = ``cur``."""
    n_levels = grid.size
    if mask[y, x]:
        s = np.float64(sigma[y, x, c])
        s = ZERO if s < 0.0 else s
        s = grid[n_levels - 1] if s > grid[n_levels - 1] else s
        hi = 0
        while hi < n_levels and not grid[hi] >= s:
            hi += 1
        hi = min(max(hi, 1), n_levels - 1)
        if hi == k:
            wt = f32((s - grid[k - 1]) / (grid[k] - grid[k - 1]))
            out[y, x, c] = (ONE - wt) * prev[c, y, x] + wt * cur
    prev[c, y, x] = cur


@njit(cache=True, parallel=True, error_model="numpy")
def spread_light(e, mask, sigma, grid, n_full, radii, prev, out):
    """``core.techniques.combined.technique.spread_back_light`` (the reference: its docstring and
    ``core.techniques.combined.pyramid.blur``) of ``e``
    (H, W, 3) over ``mask`` with per-pixel and channel widths ``sigma`` (H, W, 3) into ``out``:
    level k (1 <= k < len(``grid``)) is the light on the mask (``e`` x mask) and the mask itself,
    each blurred by three box sums of half-width ``radii[k - 1]`` along the columns, then three
    along the rows, the light divided by the blurred mask (at least 1e-6); level 0 is ``e``. A
    pixel of the mask interpolates between the two levels whose widths ``grid`` (float64,
    ascending from 0) enclose its own (clipped to the last), as the reference's searchsorted
    picks them; elsewhere ``out`` is ``e``.

    Each box sum is the reference's: a float64 running sum along the line, from the line's start
    (zeros before it), of the float32 values, and the float32 of the difference of two of its
    values, 2 r + 1 apart, so the same float64 sums in the same order and the same roundings
    (equal to the bit). Levels are computed one after the other, each pixel's result written
    when its upper level is done: two levels and the four planes being summed are held, not the
    reference's stack of every level. Only the levels below ``n_full`` are blurred here; ``prev``
    (3, H, W) is left holding the last of them, for the wider ones on reduced grids
    (``spread_pyramid``, ``blur_reduced``, ``spread_reduced_frame``)."""
    h, w, _ = e.shape
    planes = np.empty((4, h, w), np.float32)
    for y in prange(h):
        for x in range(w):
            for c in range(3):
                prev[c, y, x] = e[y, x, c]
                out[y, x, c] = e[y, x, c]
    n_col = (w + SPREAD_STRIP - 1) // SPREAD_STRIP
    n_row = (h + SPREAD_STRIP - 1) // SPREAD_STRIP
    for k in range(1, n_full):
        r = radii[k - 1]
        for y in prange(h):
            for x in range(w):
                mk = ONE if mask[y, x] else ZERO
                planes[0, y, x] = e[y, x, 0] * mk
                planes[1, y, x] = e[y, x, 1] * mk
                planes[2, y, x] = e[y, x, 2] * mk
                planes[3, y, x] = mk
        for item in prange(4 * n_col):
            p = item // n_col
            x0 = (item % n_col) * SPREAD_STRIP
            bw = min(x0 + SPREAD_STRIP, w) - x0
            cum = np.zeros((h + 2 * r + 1, SPREAD_STRIP), np.float64)
            for _ in range(3):
                for j in range(h):
                    for t in range(bw):
                        cum[r + 1 + j, t] = cum[r + j, t] + np.float64(planes[p, j, x0 + t])
                for j in range(r):
                    for t in range(bw):
                        cum[r + 1 + h + j, t] = cum[r + h + j, t]
                for i in range(h):
                    for t in range(bw):
                        planes[p, i, x0 + t] = f32(cum[2 * r + 1 + i, t] - cum[i, t])
        for item in prange(4 * n_row):
            p = item // n_row
            y0 = (item % n_row) * SPREAD_STRIP
            cum = np.zeros(w + 2 * r + 1, np.float64)
            for y in range(y0, min(y0 + SPREAD_STRIP, h)):
                line = planes[p, y]
                for _ in range(3):
                    for j in range(w):
                        cum[r + 1 + j] = cum[r + j] + np.float64(line[j])
                    for j in range(r):
                        cum[r + 1 + w + j] = cum[r + w + j]
                    for i in range(w):
                        line[i] = f32(cum[2 * r + 1 + i] - cum[i])
        for y in prange(h):
            for x in range(w):
                den = planes[3, y, x]
                den = den if den > f32(1e-6) or den != den else f32(1e-6)
                for c in range(3):
                    _frame_level(mask, sigma, grid, k, y, x, c, planes[c, y, x] / den, prev, out)


@njit(cache=True, inline="always", error_model="numpy")
def _ring(r):
    """Rows of ``_running_box``'s ring of running sums for half-width ``r``: a power of two
    holding the 2 r + 2 it reads at once."""
    n = 1
    while n < 2 * r + 2:
        n *= 2
    return n


@njit(cache=True, error_model="numpy")
def _running_box(buf, cum, lo, hi, out_lo, out_hi, r, bw):
    """One box sum of half-width ``r`` along the first axis of the first ``bw`` columns of
    ``buf``, whose rows ``lo``..``hi`` - 1 hold the values (zero beyond them, where the
    reference's values are zero or its box ends): the float64 running sum of the values from
    ``lo``, and for the rows ``out_lo``..``out_hi`` - 1 the float32 of the difference of its values
    2 r + 1 apart, as ``core.techniques.combined.pyramid.box_sum``'s cumulative sums give it (zeros before the first
    value add nothing). Vectorized across the columns. The running sums are kept in ``cum``, a
    ring of ``_ring(r)`` rows (the sum of the first k values in row k mod its size), which stays
    in the cache where a whole line's would not; a row of ``buf`` is overwritten once summed."""
    n = hi - lo
    mask = cum.shape[0] - 1
    for t in range(bw):
        cum[0, t] = 0.0
    done = 0
    for i in range(out_lo, out_hi):
        a = min(max(i + r + 1 - lo, 0), n)
        b = min(max(i - r - lo, 0), n)
        while done < a:
            src = done & mask
            dst = (done + 1) & mask
            for t in range(bw):
                cum[dst, t] = cum[src, t] + np.float64(buf[done, t])
            done += 1
        ra = a & mask
        rb = b & mask
        for t in range(bw):
            buf[i - lo, t] = f32(cum[ra, t] - cum[rb, t])


#: Rows of a part ``spread_band``'s horizontal passes sum together (their four planes side by
#: side: the running sums' chains of additions are independent, 16 float64 lanes).
SPREAD_ROWS = 4


@njit(cache=True, inline="always", error_model="numpy")
def _ready(m, r, n):
    """How many outputs of a box sum of half-width ``r`` over ``n`` values are ready once ``m`` of
    them are summed: output i takes the running sum up to min(i + r + 1, n)."""
    return n if m >= n else max(0, m - r)


@njit(cache=True, inline="always", error_model="numpy")
def _push(ring, m, vals, bw):
    """The running sum after ``m`` + 1 values: the one after ``m`` plus ``vals`` (float64), in the
    ring ``ring`` (rows: its length; the sum of the first k values in row k mod it)."""
    n = ring.shape[0]
    src = m % n
    dst = (m + 1) % n
    for t in range(bw):
        ring[dst, t] = ring[src, t] + np.float64(vals[t])


@njit(cache=True, inline="always", error_model="numpy")
def _take(ring, i, r, n, out, bw):
    """Output ``i`` of the box sum: the float32 of the running sums' difference 2 r + 1 apart
    (clipped to the ``n`` values), as ``_running_box`` gives it."""
    rows = ring.shape[0]
    a = min(i + r + 1, n) % rows
    b = max(i - r, 0) % rows
    for t in range(bw):
        out[t] = f32(ring[a, t] - ring[b, t])


@njit(cache=True, inline="always", error_model="numpy")
def _band_columns(light, on, part, state, base, rows, q, xs, bw, b0, t_from, t_to, lo, n, r, planes, l0, o0):
    """``spread_band``'s vertical pass of plane ``q`` (R, G, B or the mask) over one strip of
    ``bw`` columns from region column ``xs``: its three rings of ``rows`` running sums at
    ``state[base:]`` (set to zero in the part's first band), fed the rows ``t_from``..``t_to`` - 1
    (the values from row ``lo``, ``n`` of them), the three box sums of half-width ``r`` chained,
    and the third sum's rows of the band from ``b0`` into ``planes``."""
    ring1 = state[base : base + rows * PART_STRIP].reshape((rows, PART_STRIP))
    ring2 = state[base + rows * PART_STRIP : base + 2 * rows * PART_STRIP].reshape((rows, PART_STRIP))
    ring3 = state[base + 2 * rows * PART_STRIP : base + 3 * rows * PART_STRIP].reshape((rows, PART_STRIP))
    if b0 == part[0]:
        for t in range(bw):
            ring1[0, t] = 0.0
            ring2[0, t] = 0.0
            ring3[0, t] = 0.0
    x = np.zeros(PART_STRIP, np.float32)
    y1 = np.empty(PART_STRIP, np.float32)
    y2 = np.empty(PART_STRIP, np.float32)
    y3 = np.empty(PART_STRIP, np.float32)
    for t_row in range(t_from, t_to):
        if part[0] <= t_row < part[1]:
            row = on[t_row - o0]
            for t in range(bw):
                mk = ONE if row[xs + t - part[2]] != 0 else ZERO
                x[t] = light[t_row - l0, xs + t, q] * mk if q < 3 else mk
        else:
            for t in range(bw):
                x[t] = ZERO
        m1 = t_row - lo
        _push(ring1, m1, x, bw)
        for i1 in range(_ready(m1, r, n), _ready(m1 + 1, r, n)):
            _take(ring1, i1, r, n, y1, bw)
            _push(ring2, i1, y1, bw)
            for i2 in range(_ready(i1, r, n), _ready(i1 + 1, r, n)):
                _take(ring2, i2, r, n, y2, bw)
                _push(ring3, i2, y2, bw)
                for i3 in range(_ready(i2, r, n), _ready(i2 + 1, r, n)):
                    i = lo + i3
                    if i < part[0] or i >= part[1]:
                        continue
                    _take(ring3, i3, r, n, y3, bw)
                    for t in range(bw):
                        planes[q, i - b0, xs + t - part[2]] = y3[t]


@njit(cache=True, inline="always", error_model="numpy")
def _band_blend(line, left, sig, on, part, needed, k, n_levels, g_lo, g_k, g_hi, top, i0, n_rows, b0, o0, out):
    """Level ``k``'s share of the part's pixels in rows ``i0``..``i0`` + ``n_rows`` - 1 (region
    rows; ``line``: their blurred planes side by side from column ``left``, four lanes a row)
    into ``out``: a pixel's channel whose width (``sig``, clipped to [0, ``top``]) lies in
    (``g_lo``, ``g_k``] adds ``k``'s weight times the level (normalized by the blurred mask) to
    the lower share already there; one in (``g_k``, ``g_hi``] takes its lower share from it."""
    for g in range(n_rows):
        i = i0 + g
        for j in range(part[2], part[3]):
            if on[i - o0, j - part[2]] == 0:
                continue
            den = line[j - left, 4 * g + 3]
            den = den if den > f32(1e-6) or den != den else f32(1e-6)
            for c in range(3):
                if not needed[k, c]:
                    continue
                s = min(max(np.float64(sig[i - b0, j, c]), 0.0), top)
                # Its levels (the reference's searchsorted): the first of grid >= s, at least 1.
                if s <= g_k and (k == 1 or s > g_lo):
                    cur = line[j - left, 4 * g + c] / den
                    wt = f32((s - g_lo) / (g_k - g_lo))
                    out[i - b0, j, c] = out[i - b0, j, c] + wt * cur
                elif k + 1 < n_levels and s > g_k and s <= g_hi:
                    cur = line[j - left, 4 * g + c] / den
                    wt = f32((s - g_k) / (g_hi - g_k))
                    out[i - b0, j, c] = (ONE - wt) * cur


@njit(cache=True, parallel=True, error_model="numpy")
def spread_band(
    light, sig, on, part, box, grid, n_full, radii, needed, row_levels, b0, b1, state, at, planes, out, l0, o0
):
    """``core.techniques.combined.technique._spread_part`` of one part's rows ``b0``..``b1`` - 1 (a band; region
    coordinates), for its levels at full resolution (the wider ones: ``spread_reduced_part``),
    into ``out`` (band rows, region columns, 3) at the part's pixels: ``light`` blurred per
    pixel and channel by ``sig`` (pixels; band rows, region columns, 3: ``band_sigma``) as
    ``spread_light`` does it, each level's three box
    sums per axis as the reference's float64 cumulative sums (``_running_box``). The part's
    pixels are ``on`` (from region row ``part[0]`` and column ``part[2]``; region rows
    ``part[0]``..``part[1]`` - 1 and columns ``part[2]``..``part[3]`` - 1 hold them all); the
    blurs are confined to ``box`` (the reference's box: the part's widened by the widest blur's
    reach and clipped to the frame).

    Only what the part's pixels read is computed, in the reference's order: the light on the
    part is zero outside its rows and columns, so a column outside them sums to zero, and so does
    a running sum before its first value; a channel's level is blurred only where a pixel's width
    lies next to it (``needed[k, c]``; ``needed[k, 3]``: the mask, for any channel).

    The bands go down the part in order, the first from ``part[0]``, and each carries the
    vertical running sums on to the next in ``state`` (float64; level k's from ``at[k]``: per
    plane and strip of ``PART_STRIP`` columns, three rings of 2 r + 2 running sums, one per
    box sum): along the columns (``_band_columns``) the three box sums of half-width r are
    chained, each value passed on as soon as its sum is complete, from the first row the
    reference's box sums read (the part's rows and 2 r beyond, within the box; every value
    summed, as in the reference's running sums) down to 3 r rows past the band (the last band:
    to the end), and the third sum's rows of the band go into ``planes`` (4, band rows, part
    columns: R, G, B and the mask). A band other than the last must end more than 3 r rows
    before that end for every level. Along the rows the same as whole rows, ``SPREAD_ROWS`` rows
    at a time, for the rows with a pixel whose width lies next to the level (the part's row i:
    levels ``row_levels[i, 0]``..``row_levels[i, 1]``). A pixel's result is (1 - w) times the
    level below its width plus w times the level above (``_band_blend``), written when the upper
    level is done (the lower one's share kept in ``out`` meanwhile); level 0 is ``light``.

    ``light`` and ``on`` may be windows of rows: their first rows are region rows ``l0`` and
    ``o0`` (``light``: 0 and ``on``: ``part[0]`` for the whole region and part; a window holds at
    least the band's rows and the 3 r rows after it that are the part's)."""
    n_levels = grid.size
    top = grid[n_levels - 1]
    pw = part[3] - part[2]
    nb = b1 - b0
    # Level 0: the lower share of the pixels whose width lies below the first blur.
    for i in prange(b0, b1):
        for j in range(part[2], part[3]):
            if on[i - o0, j - part[2]] == 0:
                continue
            for c in range(3):
                s = min(max(np.float64(sig[i - b0, j, c]), 0.0), top)
                if not grid[1] >= s:
                    continue
                wt = f32((s - grid[0]) / (grid[1] - grid[0]))
                out[i - b0, j, c] = (ONE - wt) * light[i - l0, j, c]
    n_col = (pw + PART_STRIP - 1) // PART_STRIP
    n_groups = (nb + SPREAD_ROWS - 1) // SPREAD_ROWS
    which = np.empty(4, np.int64)
    for k in range(1, n_full):
        if not needed[k, 3]:
            continue
        n_planes = 0
        for q in range(4):
            if needed[k, q]:
                which[n_planes] = q
                n_planes += 1
        r = radii[k - 1]
        lo = max(part[0] - 2 * r, box[0])
        hi = min(part[1] + 2 * r, box[1])
        n = hi - lo
        t_from = lo if b0 == part[0] else min(b0 + 3 * r, hi)
        t_to = min(b1 + 3 * r, hi)
        rows = 2 * r + 2
        size = 3 * rows * PART_STRIP
        for item in prange(n_planes * n_col):
            q = which[item // n_col]
            xs = part[2] + (item % n_col) * PART_STRIP
            bw = min(xs + PART_STRIP, part[3]) - xs
            base = at[k] + item * size
            _band_columns(light, on, part, state, base, rows, q, xs, bw, b0, t_from, t_to, lo, n, r, planes, l0, o0)
        left = max(part[2] - 2 * r, box[2])
        right = min(part[3] + 2 * r, box[3])
        g_lo = grid[k - 1]
        g_k = grid[k]
        g_hi = grid[k + 1] if k + 1 < n_levels else top
        for group in prange(n_groups):
            i0 = b0 + group * SPREAD_ROWS
            n_rows = min(SPREAD_ROWS, b1 - i0)
            wanted = False
            for g in range(n_rows):
                wanted |= row_levels[i0 + g - part[0], 0] <= k <= row_levels[i0 + g - part[0], 1]
            if not wanted:
                continue
            line = np.zeros((right - left, 4 * SPREAD_ROWS), np.float32)
            cum = np.empty((_ring(r), 4 * SPREAD_ROWS), np.float64)
            for j in range(part[2], part[3]):
                for g in range(n_rows):
                    for q in range(4):
                        line[j - left, 4 * g + q] = planes[q, i0 + g - b0, j - part[2]] if needed[k, q] else ZERO
            lanes = 4 * SPREAD_ROWS
            _running_box(line, cum, left, right, left, right, r, lanes)
            _running_box(line, cum, left, right, left, right, r, lanes)
            _running_box(line, cum, left, right, part[2], part[3], r, lanes)
            _band_blend(line, left, sig, on, part, needed, k, n_levels, g_lo, g_k, g_hi, top, i0, n_rows, b0, o0, out)


@njit(cache=True, parallel=True, error_model="numpy")
def spread_pyramid(light, on, part, box, levels, flat, band_a, band_b, l0, o0):
    """The reduced grids of ``core.techniques.combined.technique._spread_reference``'s pyramid, float32, straight from
    the light: level m's grid is ``flat[levels[m, 1]:]`` as (4, ``levels[m, 2]``, ``levels[m,
    3]``) (R, G, B and the mask; a block size ``levels[m, 0]`` of 0: not made), the float32 of
    the float64 sums of blocks of ``levels[m, 0]`` x ``levels[m, 0]`` from ``box``'s origin
    (region coordinates) of the light on the part (``light`` x ``on`` within ``part``'s rows
    and columns, 0 elsewhere in the box) and of the part itself, as ``core.techniques.combined.pyramid.block_sums``
    adds them from one factor to the next: (a00 + a01) + (a10 + a11), zeros beyond the box.
    Block sizes are powers of two, ascending (0s anywhere). Per band of rows of the largest
    block, its sums are made factor by factor, so nothing of the frame's size is held in
    float64.

    Only the bands ``band_a``..``band_b`` - 1 (of ``levels``' largest block's rows from ``box[0]``;
    ``band_b`` clipped to the box) are made, from ``light`` and ``on`` whose first rows are region
    rows ``l0`` and ``o0`` (the whole region and part: 0 and ``part[0]``; a window holds the
    bands' rows that are the part's)."""
    top_f = 1
    for m in range(levels.shape[0]):
        top_f = max(top_f, levels[m, 0])
    hb = box[1] - box[0]
    wb = box[3] - box[2]
    w2 = (wb + 1) // 2
    n_bands = (hb + top_f - 1) // top_f
    for band in prange(band_a, min(band_b, n_bands)):
        y = box[0] + band * top_f
        rows = max(top_f // 2, 1)
        sums = np.zeros((4, rows, w2), np.float64)
        # Blocks of 2 from the pixels (the reference's first core.techniques.combined.pyramid.block_sums).
        for bi in range(rows):
            for bj in range(w2):
                for q in range(4):
                    acc = 0.0
                    for dy in range(2):
                        row = 0.0
                        for dx in range(2):
                            i = y + 2 * bi + dy
                            j = box[2] + 2 * bj + dx
                            v = ZERO
                            if i < box[1] and j < box[3] and part[0] <= i < part[1] and part[2] <= j < part[3]:
                                mk = ONE if on[i - o0, j - part[2]] != 0 else ZERO
                                v = light[i - l0, j, q] * mk if q < 3 else mk
                            row = np.float64(v) if dx == 0 else row + np.float64(v)
                        acc = row if dy == 0 else acc + row
                    sums[q, bi, bj] = acc
        f = 2
        h_f = rows
        w_f = w2
        while True:
            for m in range(levels.shape[0]):
                if levels[m, 0] != f:
                    continue
                off = levels[m, 1]
                hc = levels[m, 2]
                wc = levels[m, 3]
                first = band * (top_f // f)
                for bi in range(min(h_f, hc - first)):
                    for q in range(4):
                        for bj in range(wc):
                            flat[off + (q * hc + first + bi) * wc + bj] = f32(sums[q, bi, bj])
            if f >= top_f:
                break
            # The next factor: (a00 + a01) + (a10 + a11) in place, zeros beyond an odd edge.
            h_n = (h_f + 1) // 2
            w_n = (w_f + 1) // 2
            for q in range(4):
                for bi in range(h_n):
                    for bj in range(w_n):
                        acc = 0.0
                        for dy in range(2):
                            i = 2 * bi + dy
                            row = 0.0
                            for dx in range(2):
                                j = 2 * bj + dx
                                v = sums[q, i, j] if i < h_f and j < w_f else 0.0
                                row = v if dx == 0 else row + v
                            acc = row if dy == 0 else acc + row
                        sums[q, bi, bj] = acc
            h_f, w_f, f = h_n, w_n, 2 * f


@njit(cache=True, parallel=True, error_model="numpy")
def blur_reduced(radii, reduced):
    """A reduced level's blur, in place: ``reduced`` (P, Hc, Wc) float32 (the float32 of its block
    sums, ``spread_pyramid``) through three box sums of half-widths ``radii`` along the columns
    and three along the rows, each the reference's ``core.techniques.combined.pyramid.box_sum`` (float64 running sums,
    ``_running_box``)."""
    n_planes, h, w = reduced.shape
    n_col = (w + SPREAD_STRIP - 1) // SPREAD_STRIP
    for item in prange(n_planes * n_col):
        q = item // n_col
        xs = (item % n_col) * SPREAD_STRIP
        bw = min(xs + SPREAD_STRIP, w) - xs
        buf = np.zeros((h, SPREAD_STRIP), np.float32)
        cum = np.empty((_ring(radii.max()), SPREAD_STRIP), np.float64)
        for i in range(h):
            for t in range(bw):
                buf[i, t] = reduced[q, i, xs + t]
        for r in radii:
            _running_box(buf, cum, 0, h, 0, h, r, bw)
        for i in range(h):
            for t in range(bw):
                reduced[q, i, xs + t] = buf[i, t]
    n_row = (h + SPREAD_ROWS - 1) // SPREAD_ROWS
    lanes = n_planes * SPREAD_ROWS
    for group in prange(n_row):
        i0 = group * SPREAD_ROWS
        rows = min(SPREAD_ROWS, h - i0)
        line = np.zeros((w, lanes), np.float32)
        cum = np.empty((_ring(radii.max()), lanes), np.float64)
        for j in range(w):
            for g in range(rows):
                for q in range(n_planes):
                    line[j, n_planes * g + q] = reduced[q, i0 + g, j]
        for r in radii:
            _running_box(line, cum, 0, w, 0, w, r, lanes)
        for j in range(w):
            for g in range(rows):
                for q in range(n_planes):
                    reduced[q, i0 + g, j] = line[j, n_planes * g + q]


@njit(cache=True, inline="always", error_model="numpy")
def _read_axis(n, f, t):
    """``core.techniques.combined.pyramid.read_back``'s interpolation along one axis at pixel ``n`` of blocks of
    ``f`` over ``t`` of them: (first block, second block, weight of the second, float64)."""
    u = (n + 0.5) / f - 0.5
    u = min(max(u, 0.0), t - 1.0)
    i0 = min(np.int64(math.floor(u)), max(t - 2, 0))
    return i0, min(i0 + 1, t - 1), u - i0


@njit(cache=True, error_model="numpy")
def _read_columns(n0, n1, f, t):
    """``_read_axis`` of the columns ``n0``..``n1`` - 1: (first blocks, second blocks, weights)."""
    x0 = np.empty(n1 - n0, np.int64)
    x1 = np.empty(n1 - n0, np.int64)
    tx = np.empty(n1 - n0, np.float64)
    for j in range(n0, n1):
        x0[j - n0], x1[j - n0], tx[j - n0] = _read_axis(j, f, t)
    return x0, x1, tx


@njit(cache=True, inline="always", error_model="numpy")
def _read_row(reduced, y0, y1, ty, between):
    """``core.techniques.combined.pyramid.read_back``'s first step for one row: the reduced grid's rows ``y0`` and
    ``y1`` mixed by ``ty`` (float64, every plane and block column) into ``between`` (Wc, P)."""
    for jc in range(reduced.shape[2]):
        for q in range(reduced.shape[0]):
            between[jc, q] = (1.0 - ty) * np.float64(reduced[q, y0, jc]) + ty * np.float64(reduced[q, y1, jc])


@njit(cache=True, parallel=True, error_model="numpy")
def spread_reduced_part(light, sig, on, part, box, grid, n_full, flat, levels, out):
    """``spread_band``'s levels from ``n_full`` on (of ``grid``), blurred on reduced grids
    (``blur_reduced``), all in one pass over the part's pixels: level k's grid is
    ``flat[levels[k - n_full, 1]:]`` as (4, ``levels[k - n_full, 2]``, ``levels[k - n_full, 3]``)
    (R, G, B and the mask; blocks of ``levels[k - n_full, 0]`` from ``box``'s origin; a block
    size of 0: no pixel reads the level). At each pixel and channel whose width lies next to
    such a level, the grid is read back bilinearly as ``core.techniques.combined.pyramid.read_back`` does (between
    two rows, then along the row; numerator and mask in float64, each then float32), the
    numerator divided by the mask (at least 1e-6), and the pixel's share of it put into ``out``
    as ``spread_band`` does for its levels: (1 - w) times the level below its width, then plus w
    times the level above (the level below, if at full resolution, put by ``spread_band``)."""
    n_levels = grid.size
    top = grid[n_levels - 1]
    n_red = levels.shape[0]
    pw = part[3] - part[2]
    wide = 1
    for m in range(n_red):
        wide = max(wide, levels[m, 3])
    xs0 = np.zeros((n_red, pw), np.int64)
    xs1 = np.zeros((n_red, pw), np.int64)
    txs = np.zeros((n_red, pw), np.float64)
    for m in range(n_red):
        if levels[m, 0] > 0:
            for jj in range(pw):
                xs0[m, jj], xs1[m, jj], txs[m, jj] = _read_axis(part[2] + jj - box[2], levels[m, 0], levels[m, 3])
    for i in prange(part[0], part[1]):
        between = np.empty((n_red, wide, 4), np.float64)
        done = np.zeros(n_red, np.bool_)
        dens = np.empty(n_red, np.float32)
        have = np.zeros(n_red, np.bool_)
        for j in range(part[2], part[3]):
            if on[i - part[0], j - part[2]] == 0:
                continue
            jj = j - part[2]
            for m in range(n_red):
                have[m] = False
            for c in range(3):
                s = min(max(np.float64(sig[i, j, c]), 0.0), top)
                # Its levels (the reference's searchsorted): the first of grid >= s, at least 1.
                hi = 1
                while hi < n_levels - 1 and not grid[hi] >= s:
                    hi += 1
                lo = hi - 1
                if hi < n_full:
                    continue
                wt = f32((s - grid[lo]) / (grid[hi] - grid[lo]))
                for k in (lo, hi):
                    if k < n_full:
                        continue
                    m = k - n_full
                    f = levels[m, 0]
                    off = levels[m, 1]
                    hc = levels[m, 2]
                    wc = levels[m, 3]
                    if not done[m]:
                        y0, y1, ty = _read_axis(i - box[0], f, hc)
                        for jc in range(wc):
                            for q in range(4):
                                a = np.float64(flat[off + (q * hc + y0) * wc + jc])
                                b = np.float64(flat[off + (q * hc + y1) * wc + jc])
                                between[m, jc, q] = (1.0 - ty) * a + ty * b
                        done[m] = True
                    x0 = xs0[m, jj]
                    x1 = xs1[m, jj]
                    t = txs[m, jj]
                    if not have[m]:
                        den = f32((1.0 - t) * between[m, x0, 3] + t * between[m, x1, 3])
                        dens[m] = den if den > f32(1e-6) or den != den else f32(1e-6)
                        have[m] = True
                    cur = f32((1.0 - t) * between[m, x0, c] + t * between[m, x1, c]) / dens[m]
                    if k == lo:
                        out[i, j, c] = (ONE - wt) * cur
                    else:
                        out[i, j, c] = out[i, j, c] + wt * cur


@njit(cache=True, parallel=True, error_model="numpy")
def spread_reduced_frame(mask, sigma, f, reduced, grid, k, prev, out):
    """``spread_light``'s level ``k`` (of ``grid``) for a level blurred on the reduced grid
    ``reduced`` (blocks of ``f`` x ``f`` from the frame's origin): each pixel's level value (as
    ``spread_reduced_part`` reads it), with ``prev`` (the level below) into ``out`` where the
    pixel's width lies between the two, as ``spread_light`` does it; then ``prev`` = this level."""
    h, w = mask.shape
    n_planes, hc, wc = reduced.shape
    x0, x1, tx = _read_columns(0, w, f, wc)
    for y in prange(h):
        y0, y1, ty = _read_axis(y, f, hc)
        between = np.empty((wc, n_planes), np.float64)
        _read_row(reduced, y0, y1, ty, between)
        for x in range(w):
            a = x0[x]
            b = x1[x]
            t = tx[x]
            den = f32((1.0 - t) * between[a, 3] + t * between[b, 3])
            den = den if den > f32(1e-6) or den != den else f32(1e-6)
            for c in range(3):
                cur = f32((1.0 - t) * between[a, c] + t * between[b, c]) / den
                _frame_level(mask, sigma, grid, k, y, x, c, cur, prev, out)
