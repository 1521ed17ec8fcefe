"""Compiled (Numba) kernels of STA, SSSS and Burley: one fused loop per pixel, parallel over rows.

Imported only through ``core.backend`` (which sets the on-disk cache first); the technique
functions in ``core/sta.py``, ``core/ssss.py`` and ``core/burley.py`` validate their inputs,
compute what every backend shares (the pixels that take part, the footprint, the albedo split)
and hand the per-pixel work to these kernels or to their own NumPy code, the readable reference
(docs/references.md §11).

Each kernel does the reference's float32 operations in the reference's order, without fused
multiply-add: tap and sample positions, indices and comparisons come out bit-identical, so a
sample never lands on another pixel. What differs: the sums over a pixel's taps or samples may
be reassociated (``fastmath={"reassoc"}`` on the functions that hold them, so that they
vectorize; the reference sums with BLAS matrix products, in its own order), a tap's two samples
share one multiplication by its weight, and e^x is ``_exp`` (within 2 units in the last place;
NumPy's is within 4). The bound that follows is ``core.backend.tolerance``; the tests run every
technique call of the core suite on both backends against it. Where the reference multiplies a
sample by a weight of exactly 0 (a pixel that takes no part: colour 0, depth key +inf), a
kernel adds 0 (selects it away), which is the same.

Pixels are visited row by row (``prange`` over rows; SSSS's vertical pass over strips of
columns), each written by one thread only, and no kernel allocates anything the size of a frame.
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

_LOG2E = f32(1.4426950408889634)
_LN2_HI = f32(0.693359375)  # 9 significant bits: k ln2_hi is exact for |k| < 2^15
_LN2_LO = f32(-2.12194440e-4)
_EXP_MIN = f32(-87.3)  # e^x below this is under float32's smallest normal number
_C2, _C3, _C4, _C5, _C6, _C7 = (f32(1.0 / math.factorial(i)) for i in range(2, 8))


@njit(cache=True, inline="always")
def _exp(x):
    """e^x in float32 for x <= 0, within 2 units in the last place (the C library's and NumPy's
    are within 1 and 4), as arithmetic that vectorizes: x = k ln 2 + r with |r| <= ln(2) / 2
    (Cody and Waite's two-part ln 2), e^r by its Taylor polynomial to r^7 (truncation below
    4e-9), 2^k from the exponent bits. 0 below -87.3 (the reference gives at most 1.2e-38 there)."""
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


@njit(cache=True, inline="always")
def _clip(v, hi):
    """min(max(v, 0), hi) as np.clip gives it; NaN gives 0 (an index must never be NaN)."""
    v = v if v > _ZERO else _ZERO
    return v if v < hi else hi


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
def _unit(x, y, z):
    """(x, y, z, |v|) normalized as core.sta._norm does it."""
    length = x * x
    length += y * y
    length += z * z
    length = math.sqrt(length)
    inv = _ONE / (length if length > _TINY else _TINY)
    return x * inv, y * inv, z * inv, length


@njit(cache=True, parallel=True)
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

    Per row, one loop over the masked span per light (the light's kind fixed in the loop, so
    that it vectorizes over the pixels), with the sums kept in row buffers."""
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
        buf = np.empty((11, m), np.float32)
        nxr, nyr, nzr, vxr, vyr, vzr, tr, grey, c0, c1, c2 = buf
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
            kind = int(lights[k, 0])
            is_grey = lights[k, 14] != _ZERO
            for i in range(m):
                x = x0 + i
                if kind == SUN:
                    lx = lights[k, 1]
                    ly = lights[k, 2]
                    lz = lights[k, 3]
                    e = lights[k, 7]
                else:
                    lx, ly, lz, dist = _unit(
                        lights[k, 1] - position[y, x, 0],
                        lights[k, 2] - position[y, x, 1],
                        lights[k, 3] - position[y, x, 2],
                    )
                    r2 = dist * dist
                    r2 = r2 if r2 > _R2_MIN else _R2_MIN
                    if kind == AREA:
                        cos_l = lx * lights[k, 4]
                        cos_l += ly * lights[k, 5]
                        cos_l += lz * lights[k, 6]
                        cos_l = -cos_l
                        cos_l = cos_l if cos_l > _ZERO else _ZERO
                        e = lights[k, 7] * cos_l / r2
                    else:
                        e = lights[k, 7] / r2
                        if kind == SPOT:
                            ca = lx * lights[k, 4]
                            ca += ly * lights[k, 5]
                            ca += lz * lights[k, 6]
                            tc = -ca - lights[k, 11]
                            cone = _ONE if tc > _ZERO else _ZERO
                            if lights[k, 13] != _ZERO:
                                u = _clip((tc - _ZERO) / lights[k, 12], _ONE)
                                cone = cone * (u * u * (_THREE - _TWO * u))
                            e = e * cone
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
                vdot *= f32(-1.0) / (length if length > _TINY else _TINY)
                if power == _ZERO:
                    lobe = _ONE if vdot > _ZERO else _ZERO
                else:
                    lobe = vdot if vdot > _ZERO else _ZERO
                    if power == _TWO:
                        lobe = lobe * lobe  # x^2 rounded once, as powf and NumPy's square give it
                    elif power != _ONE:
                        lobe = lobe**power
                if length <= _EPS:
                    lobe = _ZERO
                e_pi = e * f32(1.0 / math.pi)
                if kind == SUN:
                    lobe *= scale * e_pi
                    if ambient != _ZERO:
                        lobe += ambient * e_pi
                else:
                    lobe *= scale
                    lobe += ambient
                    lobe *= e_pi
                if is_grey:
                    if lights[k, 8] != _ONE:
                        lobe *= lights[k, 8]
                    grey[i] = lobe if first_grey else grey[i] + lobe
                else:
                    c0[i] += lights[k, 8] * lobe
                    c1[i] += lights[k, 9] * lobe
                    c2[i] += lights[k, 10] * lobe
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


@njit(cache=True, fastmath={"reassoc"})
def _ssss_pixel(src, src_base, key, key_base, stride, kc, s, coord, last, offsets, weights, sums):
    """The off-centre taps of one 1-D SSSS pass (core.ssss._pass) for one pixel, summed into
    ``sums`` (6,): per channel sum_k w_k a_k and sum_k w_k a_k g_k.

    ``src`` (flat RGB) and ``key`` (flat) are read along a line: its pixel j at
    ``src_base + j * stride`` and ``key_base + j * stride``. ``src`` holds 0 and ``key`` +inf
    where pixels take no part (their weight is then exactly 0); ``kc`` is the pixel's key,
    ``s`` its pixels per scene unit, ``coord`` its position along the line of ``last + 1``
    pixels. Only the sums (and the products of a tap's two samples with its weight) may be
    reassociated (they vectorize over the taps); the tap positions are the reference's."""
    lastf = f32(last)
    aw0 = _ZERO
    aw1 = _ZERO
    aw2 = _ZERO
    ag0 = _ZERO
    ag1 = _ZERO
    ag2 = _ZERO
    for k in range(offsets.size):
        pos = s * offsets[k]
        pos += coord
        pos = _clip(pos, lastf)
        fl = np.floor(pos)
        f = pos - fl
        j = int(fl)
        j1 = j + 1 if j < last else j  # past the end only when f = 0: weight 0 either way
        p0 = j * stride
        p1 = j1 * stride
        a0 = _ONE - abs(key[key_base + p0] - kc)
        a0 = (a0 if a0 > _ZERO else _ZERO) * (_ONE - f)
        a1 = _ONE - abs(key[key_base + p1] - kc)
        a1 = (a1 if a1 > _ZERO else _ZERO) * f
        i0 = (src_base + p0) * 3
        i1 = (src_base + p1) * 3
        aw0 += (a0 + a1) * weights[k, 0]
        aw1 += (a0 + a1) * weights[k, 1]
        aw2 += (a0 + a1) * weights[k, 2]
        ag0 += (a0 * src[i0] + a1 * src[i1]) * weights[k, 0]
        ag1 += (a0 * src[i0 + 1] + a1 * src[i1 + 1]) * weights[k, 1]
        ag2 += (a0 * src[i0 + 2] + a1 * src[i1 + 2]) * weights[k, 2]
    sums[0] = aw0
    sums[1] = aw1
    sums[2] = aw2
    sums[3] = ag0
    sums[4] = ag1
    sums[5] = ag2


#: Columns per work item of SSSS's vertical pass: a strip of the frame is copied into a buffer
#: that stays in the cache (16 columns x 2160 rows x 3 channels: 415 KB).
STRIP = 16


@njit(cache=True, parallel=True)
def ssss_kernel(light, key, ok, scale, offsets, weights, wsum, post, out):
    """core.ssss's two passes over the pixels ``ok`` of ``out`` (which holds the albedo times
    the light, kept where pixels take no part): along rows from ``light``, written into
    ``out``; then along columns, strip by strip of ``STRIP`` columns (a column's pass reads only
    that column), from a copy of the strip (0 where pixels take no part), times ``post``.
    ``key`` (H, W) is the depth times the follow-surface factor, +inf where pixels take no part;
    ``offsets`` (n,) the non-zero taps in scene units, ``weights`` (n, 3) theirs, ``wsum`` (3,)
    the sum of all weights. Nothing the size of a frame is allocated."""
    h, w = ok.shape
    key_flat = key.reshape(-1)
    for y in prange(h):
        x0, x1 = _span(ok[y])
        if x0 >= x1:
            continue
        # The row's light, 0 where pixels take no part (a NaN times a zero weight is NaN).
        src = np.empty(3 * w, np.float32)
        for x in range(w):
            for c in range(3):
                src[3 * x + c] = light[y, x, c] if ok[y, x] else _ZERO
        sums = np.empty(6, np.float32)
        for x in range(x0, x1):
            if ok[y, x]:
                _ssss_pixel(src, 0, key_flat, y * w, 1, key[y, x], scale[y, x], f32(x), w - 1, offsets, weights, sums)
                for c in range(3):
                    out[y, x, c] = (wsum[c] - sums[c]) * src[3 * x + c] + sums[3 + c]
    for strip in prange((w + STRIP - 1) // STRIP):
        xa = strip * STRIP
        xb = min(xa + STRIP, w)
        m = xb - xa
        buf = np.empty(h * m * 3, np.float32)
        kbuf = np.empty(h * m, np.float32)
        for y in range(h):
            for i in range(m):
                x = xa + i
                kbuf[y * m + i] = key[y, x]
                for c in range(3):
                    buf[(y * m + i) * 3 + c] = out[y, x, c] if ok[y, x] else _ZERO
        sums = np.empty(6, np.float32)
        for y in range(h):
            for i in range(m):
                x = xa + i
                if ok[y, x]:
                    _ssss_pixel(buf, i, kbuf, i, m, kbuf[y * m + i], scale[y, x], f32(y), h - 1, offsets, weights, sums)
                    q = (y * m + i) * 3
                    for c in range(3):
                        out[y, x, c] = ((wsum[c] - sums[c]) * buf[q + c] + sums[3 + c]) * post[y, x, c]


@njit(cache=True, fastmath={"reassoc"})
def _burley_pixel(light, zkey, ids, y, x, s, rc, rsn, r_su, r2, cos_a, sin_a, inv_pdf, inv3d, sums):
    """The spiral samples of pixel (y, x) as core.burley computes them, summed into ``sums``
    (num R, G, B, den R, G, B). ``zkey`` (H, W): the depth where pixels take part, +inf
    elsewhere. ``rc``/``rsn``: the pixel's rotation (1, 0 for none); ``ids``
    flat object ids, or one 0 when there are none. A sample the reference weights by exactly 0
    (off the image, off the mask, another object) is selected away (its light may be NaN).
    Only the sums over the samples may be reassociated (they vectorize); the sample positions
    are the reference's to the bit (the tests compare both backends)."""
    h, w = zkey.shape
    wl = f32(w - 1)
    hl = f32(h - 1)
    use_ids = ids.size > 1
    own = ids[y * w + x] if use_ids else ids[0]
    zc = zkey[y, x]
    k0 = -inv3d[0]
    k1 = -inv3d[1]
    k2 = -inv3d[2]
    n0 = _ZERO
    n1 = _ZERO
    n2 = _ZERO
    d0 = _ZERO
    d1 = _ZERO
    d2 = _ZERO
    for i in range(r_su.size):
        ca = rc * cos_a[i] - rsn * sin_a[i]
        sa = rsn * cos_a[i] + rc * sin_a[i]
        rad = s * r_su[i]
        xs = rad * ca
        xs += f32(x)
        xs = np.rint(xs)
        ys = rad * sa
        ys += f32(y)
        ys = np.rint(ys)
        xc = _clip(xs, wl)
        yc = _clip(ys, hl)
        jx = int(xc)
        jy = int(yc)
        zj = zkey[jy, jx]
        other = ids[jy * w + jx] if use_ids else own
        valid = (xc == xs) & (yc == ys) & (zj < _INF) & (other == own)
        rp = zj - zc
        rp *= rp
        rp += r2[i]
        rp = math.sqrt(rp)
        ratio = inv_pdf[i] / (rp if rp > _TINY else _TINY)
        e3 = _exp(rp * k0)
        w0 = (e3 * e3 * e3 + e3) * ratio
        e3 = _exp(rp * k1)
        w1 = (e3 * e3 * e3 + e3) * ratio
        e3 = _exp(rp * k2)
        w2 = (e3 * e3 * e3 + e3) * ratio
        d0 += w0 if valid else _ZERO
        d1 += w1 if valid else _ZERO
        d2 += w2 if valid else _ZERO
        n0 += w0 * light[jy, jx, 0] if valid else _ZERO
        n1 += w1 * light[jy, jx, 1] if valid else _ZERO
        n2 += w2 * light[jy, jx, 2] if valid else _ZERO
    sums[0] = n0
    sums[1] = n1
    sums[2] = n2
    sums[3] = d0
    sums[4] = d1
    sums[5] = d2


@njit(cache=True, parallel=True)
def burley_kernel(light, zkey, ok, scale, ids, group, tables, rot_cos, rot_sin, inv3d, reach, post, out):
    """core.burley's gather over the pixels ``ok`` into ``out`` (times ``post``).

    ``zkey`` (H, W): the depth where ``ok``, +inf elsewhere (so that a sample's test of the
    pixel it reads is one float comparison, not a gather of bytes); ``tables`` (5, G, n): per
    object group the spiral's radii, radii squared, cosines, sines and inverse pdfs;
    ``group`` (H, W) each pixel's group, or (1, 1) for one group;
    ``reach`` (3,) float64, 16 d_c per channel (0: the channel keeps its light; so does a
    channel whose reach times the pixel's scale is at most one pixel); ``rot_cos``/``rot_sin``
    (H, W) the per-pixel rotation as NumPy computed it, or (1, 1) holding 1 and 0 for none;
    ``ids`` flat int64 object ids, or one 0 for none."""
    h, w = ok.shape
    rotate = rot_cos.size > 1
    grouped = group.size > 1
    for y in prange(h):
        sums = np.empty(6, np.float32)
        for x in range(w):
            if not ok[y, x]:
                continue
            s = scale[y, x]
            rc = rot_cos[y, x] if rotate else rot_cos[0, 0]
            rsn = rot_sin[y, x] if rotate else rot_sin[0, 0]
            g = group[y, x] if grouped else 0
            _burley_pixel(
                light, zkey, ids, y, x, s, rc, rsn, tables[0, g], tables[1, g], tables[2, g], tables[3, g],
                tables[4, g], inv3d, sums,
            )  # fmt: skip
            for c in range(3):
                den = sums[3 + c]
                if reach[c] <= 0.0 or reach[c] * np.float64(s) <= 1.0 or den <= _TINY:
                    v = light[y, x, c]
                else:
                    v = sums[c] / den
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
