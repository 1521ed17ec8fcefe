"""Compiled (Numba) kernels of STA, SSSS and Burley: one fused loop per pixel, parallel over rows.

Imported only through ``core.backend`` (which sets the on-disk cache first); the technique
functions in ``core/sta.py``, ``core/ssss.py`` and ``core/burley.py`` validate their inputs,
compute what every backend shares (the pixels that take part, the footprint, the albedo split)
and hand the per-pixel work to these kernels or to their own NumPy code, the readable reference
(docs/references.md §11).

Each kernel places its taps and samples with the reference's float32 operations in the
reference's order, without fused multiply-add: tap and sample positions, indices and
comparisons come out bit-identical, so a sample never lands on another pixel. What differs: the
sums over a pixel's taps or samples are in another order (SSSS sums its taps one after the
other; Burley's sums over its samples are reassociated, ``fastmath={"reassoc"}`` on the
function that holds them and on nothing that places a sample, so that they vectorize; the
reference sums with BLAS matrix products, in its own order), a tap's two samples share one
multiplication by its weight, SSSS's sums of products are fused multiply-adds (one rounding
where the reference has two), and e^x is ``_exp`` (within 1 unit in the last place; NumPy's is
within 4). The bound that follows is ``core.backend.tolerance``; the tests run every technique
call of the core suite on both backends against it. Where the reference multiplies a sample by
a weight of exactly 0 (a pixel that takes no part: colour 0, depth key +inf), a kernel adds 0
(selects it away), which is the same. Burley's clean-up (``core.burley._smooth``) sums in
float64 in the reference's order: the same result to the bit, from the same gathered values.

Pixels are visited row by row (``prange`` over rows; SSSS's vertical pass over strips of
columns, Burley over blocks of rows), each written by one thread only, and no kernel allocates
anything the size of a frame. Index arithmetic in the vectorized loops is 32-bit (frames
have fewer than 2^31 / 3 pixels), so that a 512-bit register holds 16 lanes (``core.backend``
lets LLVM use them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

f32 = np.float32
_ZERO = f32(0.0)
_ONE = f32(1.0)
_TINY = f32(1e-30)
_INF = f32(np.inf)
_EPS = f32(1e-6)  # core.sta._EPS
_R2_MIN = f32(1e-12)
_QUARTER = f32(0.25)
_THREE = f32(3.0)
_TWO = f32(2.0)

# Light types as numbers for the STA kernel (core.scene.Light.type).
SUN, POINT, SPOT, AREA = 0, 1, 2, 3
#: Columns of the packed light table: type, position or direction (3), spot/area axis (3),
#: irradiance factor, colour (3), cos(half cone), smoothstep width, has a smooth edge, grey.
LIGHT_COLUMNS = 15

#: Rows per work item of the parallel loops: small enough to balance the threads when the
#: mask covers only part of the frame, large enough to amortize scheduling.
ROWS_PER_CHUNK = 4

#: Kernels whose parallel loop is over larger work items than rows, with their chunk size
#: (Burley's tiles: one per chunk).
CHUNKS = {"burley_kernel": 1}

_LOG2E = f32(1.4426950408889634)
_LN2_HI = f32(0.693359375)  # 9 significant bits: k ln2_hi is exact for |k| < 2^15
_LN2_LO = f32(-2.12194440e-4)
_EXP_MIN = f32(-87.3)  # e^x below this is under float32's smallest normal number
_C2, _C3, _C4, _C5, _C6, _C7 = (f32(1.0 / math.factorial(i)) for i in range(2, 8))


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def _exp(x):
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
    p = p * r + _ONE
    p = p * r + _ONE
    bits = (np.int32(k) + np.int32(127)) << np.int32(23)
    v = p * np.int32(bits).view(np.float32)
    return v if x >= _EXP_MIN else _ZERO


@njit(cache=True, inline="always", error_model="numpy")
def _clip(v, hi):
    """min(max(v, 0), hi) as np.clip gives it; NaN gives 0 (an index must never be NaN)."""
    v = v if v > _ZERO else _ZERO
    return v if v < hi else hi


@njit(cache=True, inline="always", error_model="numpy")
def _span(row):
    """(first, last + 1) of the True entries of a bool row; (0, 0) when there are none."""
    n = row.size
    x0 = 0
    while x0 < n and not row[x0]:
        x0 += 1
    x1 = n
    while x1 > x0 and not row[x1 - 1]:
        x1 -= 1
    return x0, x1


@njit(cache=True, inline="always", error_model="numpy")
def _unit(x, y, z):
    """(x, y, z, |v|) normalized as core.sta._norm does it."""
    length = x * x
    length += y * y
    length += z * z
    length = math.sqrt(length)
    inv = _ONE / (length if length > _TINY else _TINY)
    return x * inv, y * inv, z * inv, length


@njit(cache=True, error_model="numpy")
def _sta_light(k, lights, position, y, x0, m, distortion, nxr, nyr, nzr, vxr, vyr, vzr, vd, lens, er):
    """Light ``k`` over the row's span: V . normalize(L + d_T N) negated into ``vd``,
    |L + d_T N| into ``lens`` and, for other lights than suns, the irradiance into ``er``
    (a sun's is ``lights[k, 7]``). One loop per kind of light, so that each vectorizes."""
    kind = int(lights[k, 0])
    if kind == SUN:
        lx = lights[k, 1]
        ly = lights[k, 2]
        lz = lights[k, 3]
        for i in range(m):
            ux = distortion * nxr[i]
            ux += lx
            uy = distortion * nyr[i]
            uy += ly
            uz = distortion * nzr[i]
            uz += lz
            length = ux * ux
            length += uy * uy
            length += uz * uz
            length = math.sqrt(length)
            vdot = vxr[i] * ux
            vdot += vyr[i] * uy
            vdot += vzr[i] * uz
            vd[i] = vdot * (f32(-1.0) / (length if length > _TINY else _TINY))
            lens[i] = length
        return
    cx = lights[k, 1]
    cy = lights[k, 2]
    cz = lights[k, 3]
    ax = lights[k, 4]
    ay = lights[k, 5]
    az = lights[k, 6]
    e7 = lights[k, 7]
    half = lights[k, 11]
    width = lights[k, 12]
    smooth = lights[k, 13] != _ZERO
    for i in range(m):
        lx, ly, lz, dist = _unit(cx - position[y, x0 + i, 0], cy - position[y, x0 + i, 1], cz - position[y, x0 + i, 2])
        r2 = dist * dist
        r2 = r2 if r2 > _R2_MIN else _R2_MIN
        if kind == AREA:
            cos_l = lx * ax
            cos_l += ly * ay
            cos_l += lz * az
            cos_l = -cos_l
            cos_l = cos_l if cos_l > _ZERO else _ZERO
            e = e7 * cos_l / r2
        else:
            e = e7 / r2
            if kind == SPOT:
                ca = lx * ax
                ca += ly * ay
                ca += lz * az
                tc = -ca - half
                cone = _ONE if tc > _ZERO else _ZERO
                if smooth:
                    u = _clip((tc - _ZERO) / width, _ONE)
                    cone = cone * (u * u * (_THREE - _TWO * u))
                e = e * cone
        er[i] = e
        ux = distortion * nxr[i]
        ux += lx
        uy = distortion * nyr[i]
        uy += ly
        uz = distortion * nzr[i]
        uz += lz
        length = ux * ux
        length += uy * uy
        length += uz * uz
        length = math.sqrt(length)
        vdot = vxr[i] * ux
        vdot += vyr[i] * uy
        vdot += vzr[i] * uz
        vd[i] = vdot * (f32(-1.0) / (length if length > _TINY else _TINY))
        lens[i] = length


@njit(cache=True, error_model="numpy")
def _sta_lobe(power, m, vd, lens):
    """max(0, vd)^power in place (power 0: 1 where vd > 0), 0 where the direction vanished;
    the common powers without a call to pow, so that the loop vectorizes."""
    if power == _ZERO:
        for i in range(m):
            vd[i] = _ONE if vd[i] > _ZERO and lens[i] > _EPS else _ZERO
    elif power == _TWO:
        for i in range(m):
            v = vd[i] if vd[i] > _ZERO else _ZERO
            vd[i] = v * v if lens[i] > _EPS else _ZERO  # x^2 rounded once, as NumPy's square gives it
    elif power == _ONE:
        for i in range(m):
            v = vd[i] if vd[i] > _ZERO else _ZERO
            vd[i] = v if lens[i] > _EPS else _ZERO
    else:
        for i in range(m):
            v = vd[i] if vd[i] > _ZERO else _ZERO
            vd[i] = v**power if lens[i] > _EPS else _ZERO


@njit(cache=True, parallel=True, error_model="numpy")
def sta_kernel(
    albedo,
    normal,
    position,
    thickness,
    mask,
    lights,
    ortho,
    view,
    distortion,
    power,
    scale,
    ambient,
    flip,
    burley,
    distance,
    three_d,
    out,
):
    """core.sta.sta's per-pixel arithmetic (its docstring has the formulas) into ``out``
    (H, W, 3), which holds zeros; ``lights`` is the (L, LIGHT_COLUMNS) table of
    ``light_table``; with ``burley`` each channel is scaled by the transmittance through
    ``distance`` sqrt(1 - t) for the profile lengths ``three_d`` = 3 d_c (0: no scattering).

    Per row, loops over the masked span that each do one thing for all its pixels (the
    pixel's vectors; per light its lobe, ``_sta_light`` and ``_sta_lobe``, then its sum), with
    the values kept in row buffers, so that every loop vectorizes over the pixels."""
    h, w = mask.shape
    n_lights = lights.shape[0]
    has_grey = False
    has_col = False
    for k in range(n_lights):
        if lights[k, 14] != _ZERO:
            has_grey = True
        else:
            has_col = True
    for y in prange(h):
        x0, x1 = _span(mask[y])
        if x0 >= x1:
            continue
        m = x1 - x0
        # One contiguous buffer per value (views of rows of one 2-D buffer would be strided
        # arrays to Numba: gathers and scatters instead of vector loads and stores).
        nxr, nyr, nzr = np.empty(m, np.float32), np.empty(m, np.float32), np.empty(m, np.float32)
        vxr, vyr, vzr = np.empty(m, np.float32), np.empty(m, np.float32), np.empty(m, np.float32)
        tr, grey, c0 = np.empty(m, np.float32), np.empty(m, np.float32), np.empty(m, np.float32)
        c1, c2 = np.empty(m, np.float32), np.empty(m, np.float32)
        vd, lens, er = np.empty(m, np.float32), np.empty(m, np.float32), np.empty(m, np.float32)
        okr = np.empty(m, np.bool_)
        for i in range(m):
            x = x0 + i
            a0 = albedo[y, x, 0]
            s = a0 + albedo[y, x, 1]
            s += albedo[y, x, 2]
            nx = normal[y, x, 0]
            ny = normal[y, x, 1]
            nz = normal[y, x, 2]
            px = position[y, x, 0]
            py = position[y, x, 1]
            pz = position[y, x, 2]
            t = thickness[y, x]
            s += nx
            s += ny
            s += nz
            s += px
            s += py
            s += pz
            s += t
            okr[i] = mask[y, x] and np.isfinite(s)
            t = _clip(t, _ONE)
            tr[i] = _ONE - t if flip else t
            nxr[i], nyr[i], nzr[i], _ = _unit(nx, ny, nz)
            if ortho:
                vxr[i] = view[0]
                vyr[i] = view[1]
                vzr[i] = view[2]
            else:
                vxr[i], vyr[i], vzr[i], _ = _unit(view[0] - px, view[1] - py, view[2] - pz)
            grey[i] = _ZERO
            c0[i] = _ZERO
            c1[i] = _ZERO
            c2[i] = _ZERO
        first_grey = True
        for k in range(n_lights):
            sun = int(lights[k, 0]) == SUN
            is_grey = lights[k, 14] != _ZERO
            _sta_light(k, lights, position, y, x0, m, distortion, nxr, nyr, nzr, vxr, vyr, vzr, vd, lens, er)
            _sta_lobe(power, m, vd, lens)
            e_sun_pi = lights[k, 7] * f32(1.0 / math.pi)
            sun_scale = scale * e_sun_pi
            sun_ambient = ambient * e_sun_pi
            col0 = lights[k, 8]
            col1 = lights[k, 9]
            col2 = lights[k, 10]
            tint = is_grey and col0 != _ONE
            for i in range(m):
                lobe = vd[i]
                if sun:
                    lobe *= sun_scale
                    if ambient != _ZERO:
                        lobe += sun_ambient
                else:
                    lobe *= scale
                    lobe += ambient
                    lobe *= er[i] * f32(1.0 / math.pi)
                if is_grey:
                    if tint:
                        lobe *= col0
                    grey[i] = lobe if first_grey else grey[i] + lobe
                else:
                    c0[i] += col0 * lobe
                    c1[i] += col1 * lobe
                    c2[i] += col2 * lobe
            if is_grey:
                first_grey = False
        for i in range(m):
            x = x0 + i
            t = tr[i]
            if burley:
                xs = _ONE - t
                xs = distance * math.sqrt(xs if xs > _ZERO else _ZERO)
                for c in range(3):
                    if has_col:
                        light = (c0[i] if c == 0 else c1[i] if c == 1 else c2[i]) + (grey[i] if has_grey else _ZERO)
                    else:
                        light = grey[i]
                    if three_d[c] > _ZERO:
                        e3 = _exp(-xs / three_d[c])
                        tm = _QUARTER * (e3 * e3 * e3 + _THREE * e3)
                    else:
                        tm = _ONE if xs == _ZERO else _ZERO
                    v = albedo[y, x, c] * light * tm
                    out[y, x, c] = v if okr[i] else _ZERO
            elif not has_col:
                g = grey[i] * t
                out[y, x, 0] = albedo[y, x, 0] * g if okr[i] else _ZERO
                out[y, x, 1] = albedo[y, x, 1] * g if okr[i] else _ZERO
                out[y, x, 2] = albedo[y, x, 2] * g if okr[i] else _ZERO
            else:
                for c in range(3):
                    light = c0[i] if c == 0 else c1[i] if c == 1 else c2[i]
                    if has_grey:
                        light += grey[i]
                    light *= t
                    out[y, x, c] = albedo[y, x, c] * light if okr[i] else _ZERO


@njit(cache=True, error_model="numpy")
def _ssss_positions(s, offsets, coord, last, js, fs):
    """Where a pixel's taps read, as the reference computes it: tap k reads pixels js[k] and
    js[k] + 1 with the weight fs[k] on the second. Compiled without fastmath and called from
    the kernels, never from a function with fastmath (Numba compiles a function's callees with
    its flags): the pixels read are the reference's to the bit."""
    lastf = f32(last)
    for k in range(offsets.size):
        pos = s * offsets[k]
        pos += coord
        pos = _clip(pos, lastf)
        fl = np.floor(pos)
        js[k] = np.int32(fl)
        fs[k] = pos - fl


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def _ssss_taps(lines, i, kc, js, fs, weights):
    """The off-centre taps of one 1-D SSSS pass (core.ssss._pass) for one pixel, read where
    ``_ssss_positions`` put them: per channel sum_k w_k a_k and sum_k w_k a_k g_k, as
    (aw R, G, B, ag R, G, B).

    ``lines[i]`` (4, last + 2): the line's light R, G, B and key (the line's last + 1 pixels,
    then (0, 0, 0, +inf), the neighbour the reference gives the line's last pixel), 0 and +inf
    where pixels take no part (their weight is then exactly 0); ``kc`` the pixel's key.

    One tap at a time, in scalar code: vectorized over the taps, as the reference's matrix
    products are, the gathers and the sums across the vector cost more than the taps (measured:
    334 vs 222 ms per pass at 1080p). The sums are in the taps' order (the reference's matrix
    products sum in their own), with their products fused into them (``fastmath`` "contract":
    one rounding instead of two)."""
    aw0 = _ZERO
    aw1 = _ZERO
    aw2 = _ZERO
    ag0 = _ZERO
    ag1 = _ZERO
    ag2 = _ZERO
    for k in range(js.size):
        j = js[k]
        f = fs[k]
        j1 = np.int32(j + np.int32(1))  # the padding past the end only when f = 0: weight 0
        a0 = _ONE - abs(lines[i, 3, j] - kc)
        a0 = (a0 if a0 > _ZERO else _ZERO) * (_ONE - f)
        a1 = _ONE - abs(lines[i, 3, j1] - kc)
        a1 = (a1 if a1 > _ZERO else _ZERO) * f
        aw = a0 + a1
        w0 = weights[k, 0]
        w1 = weights[k, 1]
        w2 = weights[k, 2]
        aw0 += aw * w0
        aw1 += aw * w1
        aw2 += aw * w2
        ag0 += (a0 * lines[i, 0, j] + a1 * lines[i, 0, j1]) * w0
        ag1 += (a0 * lines[i, 1, j] + a1 * lines[i, 1, j1]) * w1
        ag2 += (a0 * lines[i, 2, j] + a1 * lines[i, 2, j1]) * w2
    return aw0, aw1, aw2, ag0, ag1, ag2


#: Columns per work item of SSSS's vertical pass: a strip of the frame is copied, column by
#: column, into line buffers that stay in the cache (16 columns x 2161 rows x 4 values: 553 KB).
STRIP = 16


@njit(cache=True, parallel=True, error_model="numpy")
def ssss_kernel(light, key, ok, scale, offsets, weights, wsum, post, out):
    """core.ssss's two passes over the pixels ``ok`` of ``out`` (which holds the albedo times
    the light, kept where pixels take no part): along rows from ``light``, written into
    ``out``; then along columns, strip by strip of ``STRIP`` columns (a column's pass reads only
    that column), from a copy of the strip (0 where pixels take no part), times ``post``.
    ``key`` (H, W) is the depth times the follow-surface factor, +inf where pixels take no part;
    ``offsets`` (n,) the non-zero taps in scene units, ``weights`` (n, 3) theirs, ``wsum`` (3,)
    the sum of all weights. Each line is read from planar buffers (R, G, B, key) of the line
    plus one padding pixel. Nothing the size of a frame is allocated."""
    h, w = ok.shape
    for y in prange(h):
        x0, x1 = _span(ok[y])
        if x0 >= x1:
            continue
        # The row's light, 0 where pixels take no part (a NaN times a zero weight is NaN).
        line = np.empty((1, 4, w + 1), np.float32)
        for x in range(w):
            o = ok[y, x]
            line[0, 0, x] = light[y, x, 0] if o else _ZERO
            line[0, 1, x] = light[y, x, 1] if o else _ZERO
            line[0, 2, x] = light[y, x, 2] if o else _ZERO
            line[0, 3, x] = key[y, x]
        line[0, 0, w] = _ZERO
        line[0, 1, w] = _ZERO
        line[0, 2, w] = _ZERO
        line[0, 3, w] = _INF
        js = np.empty(offsets.size, np.int32)
        fs = np.empty(offsets.size, np.float32)
        for x in range(x0, x1):
            if ok[y, x]:
                _ssss_positions(scale[y, x], offsets, f32(x), w - 1, js, fs)
                aw0, aw1, aw2, ag0, ag1, ag2 = _ssss_taps(line, 0, key[y, x], js, fs, weights)
                out[y, x, 0] = (wsum[0] - aw0) * line[0, 0, x] + ag0
                out[y, x, 1] = (wsum[1] - aw1) * line[0, 1, x] + ag1
                out[y, x, 2] = (wsum[2] - aw2) * line[0, 2, x] + ag2
    for strip in prange((w + STRIP - 1) // STRIP):
        xa = strip * STRIP
        xb = min(xa + STRIP, w)
        m = xb - xa
        # Rows ya..yb - 1 hold the strip's pixels that take part; the others, and the padding,
        # are (0, 0, 0, +inf), as the pixels that take no part are.
        ya = h
        yb = 0
        for y in range(h):
            for i in range(m):
                if ok[y, xa + i]:
                    ya = min(ya, y)
                    yb = y + 1
        if ya >= yb:
            continue
        lines = np.empty((m, 4, h + 1), np.float32)
        js = np.empty(offsets.size, np.int32)
        fs = np.empty(offsets.size, np.float32)
        for i in range(m):
            for c in range(3):
                lines[i, c, :ya] = _ZERO
                lines[i, c, yb:] = _ZERO
            lines[i, 3, :ya] = _INF
            lines[i, 3, yb:] = _INF
        for y in range(ya, yb):
            for i in range(m):
                x = xa + i
                o = ok[y, x]
                lines[i, 0, y] = out[y, x, 0] if o else _ZERO
                lines[i, 1, y] = out[y, x, 1] if o else _ZERO
                lines[i, 2, y] = out[y, x, 2] if o else _ZERO
                lines[i, 3, y] = key[y, x] if o else _INF
        for y in range(ya, yb):  # row by row, so that the strip's row of the output is written at once
            for i in range(m):
                x = xa + i
                if ok[y, x]:
                    _ssss_positions(scale[y, x], offsets, f32(y), h - 1, js, fs)
                    aw0, aw1, aw2, ag0, ag1, ag2 = _ssss_taps(lines, i, key[y, x], js, fs, weights)
                    out[y, x, 0] = ((wsum[0] - aw0) * lines[i, 0, y] + ag0) * post[y, x, 0]
                    out[y, x, 1] = ((wsum[1] - aw1) * lines[i, 1, y] + ag1) * post[y, x, 1]
                    out[y, x, 2] = ((wsum[2] - aw2) * lines[i, 2, y] + ag2) * post[y, x, 2]


@njit(cache=True, error_model="numpy")
def _burley_positions(xf, yf, s, rc, rsn, tables, g, wl, hl, w, js, inside):
    """Where the spiral samples of the pixel (``xf``, ``yf``) land, as the reference computes
    it: sample k reads the flat pixel js[k], which the reference keeps only if ``inside[k]``
    (the rounded position is on the image). Compiled without fastmath and called from the
    kernels, never from a function with fastmath (Numba compiles a function's callees with its
    flags): the pixels read are the reference's to the bit. The loop vectorizes (no gathers)."""
    for k in range(tables.shape[2]):
        ca = rc * tables[2, g, k] - rsn * tables[3, g, k]
        sa = rsn * tables[2, g, k] + rc * tables[3, g, k]
        rad = s * tables[0, g, k]
        xs = rad * ca
        xs += xf
        xs = np.rint(xs)
        ys = rad * sa
        ys += yf
        ys = np.rint(ys)
        xc = _clip(xs, wl)
        yc = _clip(ys, hl)
        # 32-bit index arithmetic (Numba widens integer products to 64 bits; the truncation
        # lets LLVM keep 16 lanes per 512-bit register): frames have fewer than 2^31 / 3 pixels.
        js[k] = np.int32(np.int32(yc) * np.int32(w) + np.int32(xc))
        inside[k] = (xc == xs) & (yc == ys)


@njit(cache=True, error_model="numpy", fastmath={"reassoc", "contract"})
def _burley_pixel(light, zkey, ids, q, tables, g, js, inside, k0, k1, k2, sums):
    """The spiral samples of pixel ``q``, read where ``_burley_positions`` put them, summed
    into ``sums`` (num R, G, B, den R, G, B). ``light`` flat RGB, ``zkey`` flat (the depth
    where pixels take part, +inf elsewhere), ``ids`` flat object ids or one 0 for none;
    ``tables[:, g]`` the spiral.

    The loop over the samples vectorizes (a gather per value read), with the weights and sums
    reassociated and fused (``fastmath`` "reassoc" and "contract": the sums in another order,
    one rounding instead of two, within ``core.backend.tolerance``). A sample the reference
    weights by exactly 0 (off the image, off the mask, another object) is selected away (its
    light may be NaN)."""
    use_ids = ids.size > 1
    own = ids[q] if use_ids else ids[0]
    zc = zkey[q]
    n0 = _ZERO
    n1 = _ZERO
    n2 = _ZERO
    d0 = _ZERO
    d1 = _ZERO
    d2 = _ZERO
    for k in range(js.size):
        j = js[k]
        zj = zkey[j]
        valid = inside[k] & (zj < _INF)
        if use_ids:
            valid &= ids[j] == own
        rp = zj - zc
        rp *= rp
        rp += tables[1, g, k]
        rp = math.sqrt(rp)
        ratio = tables[4, g, k] / (rp if rp > _TINY else _TINY)
        e3 = _exp(rp * k0)
        w0 = (e3 * e3 * e3 + e3) * ratio
        e3 = _exp(rp * k1)
        w1 = (e3 * e3 * e3 + e3) * ratio
        e3 = _exp(rp * k2)
        w2 = (e3 * e3 * e3 + e3) * ratio
        d0 += w0 if valid else _ZERO
        d1 += w1 if valid else _ZERO
        d2 += w2 if valid else _ZERO
        j3 = np.int32(j * np.int32(3))
        n0 += w0 * light[j3] if valid else _ZERO
        n1 += w1 * light[np.int32(j3 + np.int32(1))] if valid else _ZERO
        n2 += w2 * light[np.int32(j3 + np.int32(2))] if valid else _ZERO
    sums[0] = n0
    sums[1] = n1
    sums[2] = n2
    sums[3] = d0
    sums[4] = d1
    sums[5] = d2


@njit(cache=True, parallel=True, error_model="numpy")
def burley_zkey(ok, depth, zkey):
    """``zkey`` = the depth where ``ok``, +inf elsewhere (a sample's test of the pixel it reads
    is then one float comparison, not a gather of bytes)."""
    h, w = ok.shape
    for y in prange(h):
        for x in range(w):
            zkey[y, x] = depth[y, x] if ok[y, x] else _INF


@njit(cache=True, parallel=True, error_model="numpy")
def burley_angles(ok, seed, y0, x0, phi):
    """``phi`` (rows y0.., columns x0..): the spiral's rotation angle of each pixel of ``ok`` (0
    elsewhere), from the integer hash of its flat index and ``seed`` (its low 32 bits,
    0 <= seed < 2^32) that ``core.burley._rotation`` computes: the same unsigned 64-bit
    operations, so the same angle to the bit (the cosine and sine are then NumPy's, as the
    reference's)."""
    w = ok.shape[1]
    mixed_seed = np.uint64(seed)
    to_angle = f32(2.0 * math.pi / (1 << 24))
    for i in prange(phi.shape[0]):
        y = y0 + i
        for j in range(phi.shape[1]):
            x = x0 + j
            v = (np.uint64(y * w + x) * np.uint64(0x9E3779B97F4A7C15)) ^ mixed_seed
            v ^= v >> np.uint64(31)
            v *= np.uint64(0xBF58476D1CE4E5B9)
            v ^= v >> np.uint64(29)
            phi[i, j] = f32(v >> np.uint64(40)) * to_angle if ok[y, x] else _ZERO


#: Burley's work items are tiles of BLOCK_ROWS rows x TILE_COLS columns: the samples of a
#: tile's pixels then read a window of the frame (the tile plus the spiral's reach) that stays
#: in the second-level cache at any resolution, where whole rows' windows would not at 4K.
#: With the clean-up, a tile gathers its pixels plus ``radius`` of margin on each side
#: (recomputed by its neighbours: 2 radius / BLOCK_ROWS more work) into a buffer of the tile
#: that the clean-up reads, instead of a whole scattered frame.
BLOCK_ROWS = 32
TILE_COLS = 256


@njit(cache=True, error_model="numpy")
def _burley_tile(
    light, zkey, ok, scale, ids, group, tables, rot_cos, rot_sin, rot_y0, rot_x0, inv3d, reach, ya, yb, xa, xb, buf
):
    """core.burley's gather (the scattered light, before the albedo) of the pixels ``ok`` of
    rows ``ya``..``yb`` - 1 and columns ``xa``..``xb`` - 1 into ``buf`` (from (ya, xa), 3);
    ``rot_cos``/``rot_sin`` hold rows from ``rot_y0`` and columns from ``rot_x0``."""
    h, w = ok.shape
    rotate = rot_cos.size > 1
    grouped = group.size > 1
    wl = f32(w - 1)
    hl = f32(h - 1)
    k0 = -inv3d[0]
    k1 = -inv3d[1]
    k2 = -inv3d[2]
    light_flat = light.reshape(-1)
    zflat = zkey.reshape(-1)
    sums = np.empty(6, np.float32)
    js = np.empty(tables.shape[2], np.int32)
    inside = np.empty(tables.shape[2], np.bool_)
    for y in range(ya, yb):
        for x in range(xa, xb):
            if not ok[y, x]:
                continue
            s = scale[y, x]
            rc = rot_cos[y - rot_y0, x - rot_x0] if rotate else rot_cos[0, 0]
            rsn = rot_sin[y - rot_y0, x - rot_x0] if rotate else rot_sin[0, 0]
            g = group[y, x] if grouped else 0
            _burley_positions(f32(x), f32(y), s, rc, rsn, tables, g, wl, hl, w, js, inside)
            _burley_pixel(light_flat, zflat, ids, y * w + x, tables, g, js, inside, k0, k1, k2, sums)
            for c in range(3):
                den = sums[3 + c]
                if reach[c] <= 0.0 or reach[c] * np.float64(s) <= 1.0 or den <= _TINY:
                    v = light[y, x, c]
                else:
                    v = sums[c] / den
                buf[y - ya, x - xa, c] = v


@njit(cache=True, parallel=True, error_model="numpy")
def burley_kernel(
    light, zkey, ok, scale, ids, group, tables, rot_cos, rot_sin, rot_y0, rot_x0, inv3d, reach, extents, depth, tol,
    radius, min_px, post, y_lo, y_hi, out,
):  # fmt: skip
    """core.burley's gather and clean-up (``_smooth``, when ``radius`` > 0) over the pixels
    ``ok`` of rows ``y_lo``..``y_hi`` - 1, times ``post``, into ``out``.

    ``zkey`` (H, W): the depth where ``ok``, +inf elsewhere (``burley_zkey``); ``tables``
    (5, G, n): per object group the spiral's radii, radii squared, cosines, sines and inverse
    pdfs; ``group`` (H, W) each pixel's group, or (1, 1) for one group; ``reach`` (3,) float64,
    16 d_c per channel (0: the channel keeps its light; so does a channel whose reach times the
    pixel's scale is at most one pixel); ``rot_cos``/``rot_sin`` the per-pixel rotation as
    NumPy computed it for rows ``rot_y0``.. and columns ``rot_x0``.. (every pixel of ``ok`` in
    rows y_lo - radius .. y_hi + radius), or
    (1, 1) holding 1 and 0 for none; ``ids`` flat object ids (int32 or int64), or one 0 for
    none.

    The clean-up, per pixel of ``ok`` and channel c whose footprint (``scale`` x min(16 d_c,
    the group's extent ``extents[g]``), float64) spans at least ``min_px``: the float64 mean of
    the scattered light over the (2 ``radius`` + 1)^2 box's pixels of ``ok`` with the same id
    and |``depth`` - own depth| <= ``tol[c]``, in the reference's order (rows, then columns).
    Work items are tiles (``BLOCK_ROWS``, ``TILE_COLS``), gathered with their ``radius`` pixels
    of margin into a buffer of the tile: nothing the size of a frame is allocated."""
    h, w = ok.shape
    grouped = group.size > 1
    use_ids = ids.size > 1
    r = max(radius, 0)
    n_cols = (w + TILE_COLS - 1) // TILE_COLS
    n_rows = (y_hi - y_lo + BLOCK_ROWS - 1) // BLOCK_ROWS
    for tile in prange(n_rows * n_cols):
        y0 = y_lo + (tile // n_cols) * BLOCK_ROWS
        y1 = min(y0 + BLOCK_ROWS, y_hi)
        x0 = (tile % n_cols) * TILE_COLS
        x1 = min(x0 + TILE_COLS, w)
        ya = max(y0 - r, 0)
        yb = min(y1 + r, h)
        xa = max(x0 - r, 0)
        xb = min(x1 + r, w)
        any_ok = False
        for y in range(y0, y1):
            for x in range(x0, x1):
                any_ok |= ok[y, x]
        if not any_ok:
            continue
        buf = np.empty((yb - ya, xb - xa, 3), np.float32)
        _burley_tile(
            light, zkey, ok, scale, ids, group, tables, rot_cos, rot_sin, rot_y0, rot_x0, inv3d, reach, ya, yb, xa, xb,
            buf,
        )  # fmt: skip
        for y in range(y0, y1):
            for x in range(x0, x1):
                if not ok[y, x]:
                    continue
                px = np.float64(scale[y, x])
                g = group[y, x] if grouped else 0
                zc = depth[y, x]
                own = ids[y * w + x] if use_ids else ids[0]
                for c in range(3):
                    v = buf[y - ya, x - xa, c]
                    if r > 0 and px * min(reach[c], extents[g]) >= min_px:
                        total = 0.0
                        count = 0.0
                        for ny in range(max(y - r, 0), min(y + r + 1, h)):
                            for nx in range(max(x - r, 0), min(x + r + 1, w)):
                                if not ok[ny, nx] or (use_ids and ids[ny * w + nx] != own):
                                    continue
                                if abs(depth[ny, nx] - zc) <= tol[c]:
                                    total += np.float64(buf[ny - ya, nx - xa, c])
                                    count += 1.0
                        v = f32(total / max(count, 1.0))
                    out[y, x, c] = post[y, x, c] * v


def light_table(lights) -> np.ndarray:
    """core.scene.Light list as the STA kernel's (L, LIGHT_COLUMNS) float32 table, each value
    rounded to float32 exactly where ``core.sta.light_at`` rounds it."""
    table = np.zeros((len(lights), LIGHT_COLUMNS), np.float32)
    for k, light in enumerate(lights):
        row = table[k]
        if light.type == "SUN":
            row[0] = SUN
            row[1:4] = (-light.direction).astype(f32)
            row[7] = f32(light.energy)
        else:
            row[1:4] = light.position.astype(f32)
            row[4:7] = light.direction.astype(f32)
            if light.type == "AREA":
                row[0] = AREA
                row[7] = f32(light.energy / math.pi)
            else:
                row[0] = SPOT if light.type == "SPOT" else POINT
                row[7] = f32(light.energy / (4.0 * math.pi))
                if light.type == "SPOT":
                    half = math.cos(light.spot_size / 2.0)
                    smooth = (1.0 - half) * light.spot_blend
                    row[11] = f32(half)
                    row[12] = f32(max(smooth, 1e-30))
                    row[13] = 1.0 if smooth > 0 else 0.0
        color = np.asarray(light.color, np.float32)
        row[8:11] = color
        row[14] = 1.0 if color[0] == color[1] == color[2] else 0.0
    return table
