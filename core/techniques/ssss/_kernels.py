"""Compiled (Numba) kernel of SSSS: both 1-D passes as one kernel, over strips of columns."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ...compute.jit import INF, ONE, ZERO, clip, f32, scale_of, span, u64
from ...optics._kernels import area_at

#: Pixels per chunk of a line in SSSS's passes: the chunk's sums (6 x 4 bytes each) and the part
#: of the line its taps read stay in the first-level cache.
SSSS_CHUNK = 256

#: A tap whose runs of pixels with the same shift are shorter than this on average over a chunk
#: (estimated from the shifts of its first and last pixels, which change monotonically along a
#: surface) is read one pixel at a time (``_ssss_gathered``): a vectorized loop over a run this
#: short spends its time entering and leaving the loop (with 512-bit vectors it takes 16 pixels
#: a step, the rest one at a time). The same sums to the bit either way. Measured on the speed
#: benchmark's frame, the ``ssss_kernel`` of each material alone on one thread (the skin sphere's
#: runs are about 24 pixels long, the wax's about 3): skin 350 -> 245 ms, wax 166 -> 69 ms with
#: 32; 24 and 48 within the noise of 32.
SHORT_RUNS = 32


@njit(cache=True, inline="always", error_model="numpy")
def _ssss_pair(k0, k1, kc, f):
    """A tap's two sample weights (core.techniques.ssss.technique._pass's a0, a1): the interpolation weights 1 - ``f``
    and ``f`` times 1 - the follow-surface blend min(1, |key - ``kc``|) of each sample's key."""
    a0 = ONE - abs(k0 - kc)
    a0 = (a0 if a0 > ZERO else ZERO) * (ONE - f)
    a1 = ONE - abs(k1 - kc)
    a1 = (a1 if a1 > ZERO else ZERO) * f
    return a0, a1


@njit(cache=True, error_model="numpy")
def _ssss_shifted(lr, lg, lb, lk, kc, fb, c0, ia, ib, d, w0, w1, w2, aw0, aw1, aw2, ag0, ag1, ag2):
    """One tap for the chunk's pixels ``ia``..``ib`` - 1 (from its first pixel ``c0``), all of
    which read the line at their own coordinate plus ``d`` (and the pixel after it), with the
    interpolation weights ``fb``: contiguous loads, no gathers (unsigned indices: Numba adds no
    wrap-around test, so the loads stay contiguous and the loop vectorizes)."""
    b = u64(c0 + ia + d)
    q = u64(c0 + ia)
    ua = u64(ia)
    for t in range(ib - ia):
        ut = u64(t)
        i = ua + ut
        j = b + ut
        j1 = j + u64(1)
        f = fb[i]
        kcx = kc[q + ut]
        a0, a1 = _ssss_pair(lk[j], lk[j1], kcx, f)
        aw = a0 + a1
        aw0[i] += aw * w0
        aw1[i] += aw * w1
        aw2[i] += aw * w2
        ag0[i] += (a0 * lr[j] + a1 * lr[j1]) * w0
        ag1[i] += (a0 * lg[j] + a1 * lg[j1]) * w1
        ag2[i] += (a0 * lb[j] + a1 * lb[j1]) * w2


@njit(cache=True, error_model="numpy")
def _ssss_shifted_area(
    lr, lg, lb, lk, la, kc, fb, ib_, c0, ia, ib, d, w0, w1, w2, aw0, aw1, aw2, ad0, ad1, ad2, ag0, ag1, ag2
):
    """``_ssss_shifted`` with the surface weight (core.techniques.ssss.technique._pass's ``area``): each sample's
    weight a also times rho = 1 + (la[j] - la[centre]) x ``ib_`` (the centre's 1 / area) as the
    reference computes it, a x (rho - 1) summed into ``ad0``..``ad2`` (the change of the total
    weight) and a x rho into the weighted sums; ``aw0``..``aw2`` keep a's sum (the part that
    falls back to the centre). The same loop over the run as ``_ssss_shifted``'s, kept as a
    loop of its own so that the paper's filter runs the loop it ran before, with no test per
    pixel."""
    b = u64(c0 + ia + d)
    q = u64(c0 + ia)
    ua = u64(ia)
    for t in range(ib - ia):
        ut = u64(t)
        i = ua + ut
        j = b + ut
        j1 = j + u64(1)
        f = fb[i]
        kcx = kc[q + ut]
        lac = la[q + ut]
        inv = ib_[i]
        a0, a1 = _ssss_pair(lk[j], lk[j1], kcx, f)
        p0 = (la[j] - lac) * inv * a0
        p1 = (la[j1] - lac) * inv * a1
        aw = a0 + a1
        aw0[i] += aw * w0
        aw1[i] += aw * w1
        aw2[i] += aw * w2
        dp = p0 + p1
        ad0[i] += dp * w0
        ad1[i] += dp * w1
        ad2[i] += dp * w2
        a0 = a0 + p0
        a1 = a1 + p1
        ag0[i] += (a0 * lr[j] + a1 * lr[j1]) * w0
        ag1[i] += (a0 * lg[j] + a1 * lg[j1]) * w1
        ag2[i] += (a0 * lb[j] + a1 * lb[j1]) * w2


@njit(cache=True, error_model="numpy")
def _ssss_gathered(lr, lg, lb, lk, la, kc, fb, db, ib_, c0, m, w0, w1, w2, aw0, aw1, aw2, ad0, ad1, ad2, ag0, ag1, ag2):
    """One tap for the chunk's ``m`` pixels from ``c0``, each reading the line at its own
    coordinate plus its shift ``db[i]``: ``_ssss_shifted`` (``la`` empty) or ``_ssss_shifted_area``
    (``la`` the surface weights) one pixel at a time, the same operations in the same order.
    For a tap whose shifts change every few pixels, where a vectorized loop over each run would
    spend its time entering and leaving the loop (``SHORT_RUNS``)."""
    weighted = la.size > 0
    for i in range(m):
        x = c0 + i
        j = u64(x + db[i])
        j1 = j + u64(1)
        a0, a1 = _ssss_pair(lk[j], lk[j1], kc[x], fb[i])
        aw = a0 + a1
        aw0[i] += aw * w0
        aw1[i] += aw * w1
        aw2[i] += aw * w2
        if weighted:
            lac = la[x]
            inv = ib_[i]
            p0 = (la[j] - lac) * inv * a0
            p1 = (la[j1] - lac) * inv * a1
            dp = p0 + p1
            ad0[i] += dp * w0
            ad1[i] += dp * w1
            ad2[i] += dp * w2
            a0 = a0 + p0
            a1 = a1 + p1
        ag0[i] += (a0 * lr[j] + a1 * lr[j1]) * w0
        ag1[i] += (a0 * lg[j] + a1 * lg[j1]) * w1
        ag2[i] += (a0 * lb[j] + a1 * lb[j1]) * w2


@njit(cache=True, inline="always", error_model="numpy")
def _ssss_weighted(n, wsum, d):
    """The surface-weighted result of one channel: the sum ``n`` times wsum / D, D = ``wsum`` +
    ``d`` (core.techniques.ssss.technique._pass; guarded: D may be 0 in a channel whose centre tap weighs 0)."""
    total = wsum + d
    return n * (wsum / total) if total > ZERO else n


@njit(cache=True, error_model="numpy")
def _ssss_line(lr, lg, lb, lk, sc, kc, lo, hi, offsets, weights, wsum, r0, r1, r2, la):
    """One 1-D SSSS pass (core.techniques.ssss.technique._pass) over the pixels ``lo``..``hi`` - 1 of one line, into
    ``r0``, ``r1``, ``r2`` (R, G, B, indexed by the coordinate).

    ``lr``, ``lg``, ``lb``, ``lk`` (last + 2,): the line's light and key (0 and +inf where
    pixels take no part, then (0, 0, 0, +inf): the neighbour the reference gives the line's last
    pixel; it is only read with weight 0); ``sc``, ``kc``: each pixel's scale and key, indexed
    by its coordinate. A pixel that takes no part gets a result that nobody reads. ``la``
    (last + 2,) the surface weights of the line's pixels (core.techniques.ssss.technique._pass's ``area``), or an
    empty array for the paper's unweighted pass.

    Vectorized across the pixels of a chunk, one tap at a time: a loop places the tap for every
    pixel with the reference's float32 operations in the reference's order (compiled without
    fastmath: no fused multiply-add, so the pixels read are the reference's to the bit), as the
    shift d = floor(position) - coordinate and the interpolation weight; then over each run of
    pixels with the same d (the whole chunk, or runs found by a scan, as the footprint varies
    slowly over a surface) the tap's samples are contiguous loads (``_ssss_shifted``), not
    gathers (measured: a vectorized gather per value made the pass slower than one pixel at a
    time). A tap whose runs are short (``SHORT_RUNS``: its outer taps, where the footprint is
    hundreds of pixels and the perspective changes it along the line) is read one pixel at a
    time (``_ssss_gathered``). Each pixel's sums are in the taps' order (the reference's matrix
    products sum in their own)."""
    lastf = f32(lr.size - 2)
    aw0 = np.empty(SSSS_CHUNK, np.float32)
    aw1 = np.empty(SSSS_CHUNK, np.float32)
    aw2 = np.empty(SSSS_CHUNK, np.float32)
    ag0 = np.empty(SSSS_CHUNK, np.float32)
    ag1 = np.empty(SSSS_CHUNK, np.float32)
    ag2 = np.empty(SSSS_CHUNK, np.float32)
    fb = np.empty(SSSS_CHUNK, np.float32)
    db = np.empty(SSSS_CHUNK, np.int32)
    weighted = la.size > 0
    ad0 = np.empty(SSSS_CHUNK, np.float32)
    ad1 = np.empty(SSSS_CHUNK, np.float32)
    ad2 = np.empty(SSSS_CHUNK, np.float32)
    inv = np.empty(SSSS_CHUNK, np.float32)
    for c0 in range(lo, hi, SSSS_CHUNK):
        m = min(SSSS_CHUNK, hi - c0)
        aw0[:m] = ZERO
        aw1[:m] = ZERO
        aw2[:m] = ZERO
        ag0[:m] = ZERO
        ag1[:m] = ZERO
        ag2[:m] = ZERO
        if weighted:
            ad0[:m] = ZERO
            ad1[:m] = ZERO
            ad2[:m] = ZERO
            for i in range(m):
                inv[i] = ONE / la[c0 + i]
        for k in range(offsets.size):
            o = offsets[k]
            w0 = weights[k, 0]
            w1 = weights[k, 1]
            w2 = weights[k, 2]
            for i in range(m):
                x = c0 + i
                pos = sc[u64(x)] * o
                pos += f32(x)
                pos = clip(pos, lastf)
                fl = np.floor(pos)
                fb[i] = pos - fl
                db[i] = np.int32(np.int32(fl) - np.int32(x))
            if m < SHORT_RUNS * (1 + abs(db[m - 1] - db[0])):
                _ssss_gathered(
                    lr, lg, lb, lk, la, kc, fb, db, inv, c0, m, w0, w1, w2, aw0, aw1, aw2, ad0, ad1, ad2, ag0, ag1,
                    ag2,
                )  # fmt: skip
                continue
            d_lo = db[0]
            d_hi = db[0]
            for i in range(m):
                d_lo = min(d_lo, db[i])
                d_hi = max(d_hi, db[i])
            # Runs of pixels with the same shift (the whole chunk, or about 90 pixels long on the
            # benchmark's spheres).
            i = 0
            while i < m:
                d = db[i]
                e = i + 1
                if d_lo != d_hi:
                    while e < m and db[e] == d:
                        e += 1
                else:
                    e = m
                if weighted:
                    _ssss_shifted_area(
                        lr, lg, lb, lk, la, kc, fb, inv, c0, i, e, d, w0, w1, w2, aw0, aw1, aw2, ad0, ad1, ad2, ag0,
                        ag1, ag2,
                    )  # fmt: skip
                else:
                    _ssss_shifted(lr, lg, lb, lk, kc, fb, c0, i, e, d, w0, w1, w2, aw0, aw1, aw2, ag0, ag1, ag2)
                i = e
        q = u64(c0)
        for i in range(m):
            ui = u64(i)
            n0 = (wsum[0] - aw0[i]) * lr[q + ui] + ag0[i]
            n1 = (wsum[1] - aw1[i]) * lg[q + ui] + ag1[i]
            n2 = (wsum[2] - aw2[i]) * lb[q + ui] + ag2[i]
            if weighted:
                n0 = _ssss_weighted(n0, wsum[0], ad0[i])
                n1 = _ssss_weighted(n1, wsum[1], ad1[i])
                n2 = _ssss_weighted(n2, wsum[2], ad2[i])
            r0[q + ui] = n0
            r1[q + ui] = n1
            r2[q + ui] = n2


#: Columns per work item of SSSS's vertical pass: the strip of the frame is copied into line
#: buffers, one per column (16 columns x 4 values x 2161 rows: 553 KB), that stay in the
#: second-level cache, in tiles of ``STRIP`` x ``STRIP`` pixels (a transposition that reads and
#: writes whole cache lines); the results go back row by row.
STRIP = 16


@njit(cache=True, parallel=True, error_model="numpy")
def ssss_kernel(light, depth, ok, cam, follow, gate, offsets, weights, wsum, post, box, area, surface, out):
    """core.techniques.ssss.technique's two passes over the pixels that take part, into ``out`` (which holds the
    albedo times the light, kept where pixels take no part): along rows from ``light``,
    written into ``out``; then along columns, strip by strip of ``STRIP`` columns (a column's
    pass reads only that column), from a copy of the strip (0 where pixels take no part), times
    ``post``.

    A pixel takes part where ``ok`` (``prepare_pixels``) and ``gate`` x scale > 0.5 (its
    kernel spans more than a pixel; scale ``scale_of`` its depth and ``cam``), both float32 as
    the reference computes them; its key is
    ``depth`` x ``follow`` (the follow-surface factor), +inf for the others. ``offsets`` (n,)
    the non-zero taps in scene units, ``weights`` (n, 3) theirs, ``wsum`` (3,) the sum of all
    weights. Each line is read from planar buffers (R, G, B, key) of the line plus one padding
    pixel (``_ssss_line``). Only the rows box[0]..box[1] - 1 and columns box[2]..box[3] - 1,
    which hold every pixel of ``ok``, are read: outside them the buffers hold (0, 0, 0, +inf),
    the value of a pixel that takes no part. Nothing the size of a frame is allocated.

    With ``surface`` an (H, W) frame, the taps weigh by the surface their pixels cover
    (core.techniques.ssss.technique's "surface" weighting; ``area`` = (far, orthographic, f, cx, cy, min_cos):
    ``surface_area``'s parameters): the row pass computes each pixel's (``area_at``) and
    writes it into ``surface`` where the pixel takes part, for the column pass. An empty
    ``surface``: the paper's unweighted passes."""
    h, w = ok.shape
    r0, r1, c0, c1 = box[0], box[1], box[2], box[3]
    half = f32(0.5)
    weighted = surface.shape[0] > 0
    far, ortho, fx, cx, cy, min_cos = area
    for y in prange(r0, r1):
        lr = np.zeros(w + 1, np.float32)
        lg = np.zeros(w + 1, np.float32)
        lb = np.zeros(w + 1, np.float32)
        lk = np.full(w + 1, INF, np.float32)
        sc = np.zeros(w, np.float32)
        okr = np.zeros(w, np.bool_)
        la = np.ones(w + 1 if weighted else 0, np.float32)
        for x in range(c0, c1):
            s = scale_of(depth[y, x], cam)
            o = ok[y, x] & (gate * s > half)
            okr[x] = o
            sc[x] = s
            # The row's light, 0 where pixels take no part (a NaN times a zero weight is NaN).
            lr[x] = light[y, x, 0] if o else ZERO
            lg[x] = light[y, x, 1] if o else ZERO
            lb[x] = light[y, x, 2] if o else ZERO
            lk[x] = depth[y, x] * follow if o else INF
            if weighted:
                la[x] = area_at(depth, ok, far, ortho, fx, cx, cy, min_cos, y, x)
        x0, x1 = span(okr[c0:c1])
        if x0 >= x1:
            continue
        res = np.empty((3, w), np.float32)
        _ssss_line(lr, lg, lb, lk, sc, lk, c0 + x0, c0 + x1, offsets, weights, wsum, res[0], res[1], res[2], la)
        for x in range(c0 + x0, c0 + x1):
            if okr[x]:
                out[y, x, 0] = res[0, x]
                out[y, x, 1] = res[1, x]
                out[y, x, 2] = res[2, x]
                if weighted:
                    surface[y, x] = la[x]
    for strip in prange((c1 - c0 + STRIP - 1) // STRIP):
        xa = c0 + strip * STRIP
        m = min(STRIP, c1 - xa)
        nl = 5 if weighted else 4
        lines = np.empty((m, nl, h + 1), np.float32)
        scs = np.zeros((m, h), np.float32)
        oks = np.zeros((m, h), np.bool_)
        res = np.empty((m, 3, h), np.float32)
        none = np.empty(0, np.float32)
        for i in range(m):
            lines[i, :3, :r0] = ZERO
            lines[i, 3, :r0] = INF
            lines[i, :3, r1:] = ZERO
            lines[i, 3, r1:] = INF
            lines[i, 4:, :r0] = ONE
            lines[i, 4:, r1:] = ONE
        for ya in range(r0, r1, STRIP):
            for i in range(m):
                x = xa + i
                for y in range(ya, min(ya + STRIP, r1)):
                    s = scale_of(depth[y, x], cam)
                    o = ok[y, x] & (gate * s > half)
                    oks[i, y] = o
                    scs[i, y] = s
                    lines[i, 0, y] = out[y, x, 0] if o else ZERO
                    lines[i, 1, y] = out[y, x, 1] if o else ZERO
                    lines[i, 2, y] = out[y, x, 2] if o else ZERO
                    lines[i, 3, y] = depth[y, x] * follow if o else INF
                    if weighted:
                        lines[i, 4, y] = surface[y, x] if o else ONE
        ya = h
        yb = 0
        for i in range(m):
            lo, hi = span(oks[i, r0:r1])
            if lo >= hi:
                continue
            ya = min(ya, r0 + lo)
            yb = max(yb, r0 + hi)
            line = lines[i]
            r = res[i]
            _ssss_line(
                line[0],
                line[1],
                line[2],
                line[3],
                scs[i],
                line[3],
                r0 + lo,
                r0 + hi,
                offsets,
                weights,
                wsum,
                r[0],
                r[1],
                r[2],
                line[4] if weighted else none,
            )
        for y in range(ya, yb):
            for i in range(m):
                if oks[i, y]:
                    x = xa + i
                    out[y, x, 0] = res[i, 0, y] * post[y, x, 0]
                    out[y, x, 1] = res[i, 1, y] * post[y, x, 1]
                    out[y, x, 2] = res[i, 2, y] * post[y, x, 2]
