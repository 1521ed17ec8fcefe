"""Compiled (Numba) kernels of STA, SSSS and Burley: one fused loop per pixel, parallel over rows.

Imported only through ``core.compute.backend`` (which sets the on-disk cache first); the technique
functions in ``core/techniques/sta/technique.py``, ``core/techniques/ssss/technique.py`` and
``core/techniques/burley/technique.py`` validate their inputs,
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
multiplication by its weight, Burley's sums of products are fused multiply-adds (one rounding
where the reference has two), and e^x is ``_exp`` (within 1 unit in the last place; NumPy's is
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
from numba import njit, prange

f32 = np.float32
_ZERO = f32(0.0)
_ONE = f32(1.0)
_TINY = f32(1e-30)
_INF = f32(np.inf)
_EPS = f32(1e-6)  # core.techniques.sta.technique._EPS
_R2_MIN = f32(1e-12)
_QUARTER = f32(0.25)
_THREE = f32(3.0)
_TWO = f32(2.0)

# Light types as numbers for the STA kernel (core.scene.scene.Light.type).
SUN, POINT, SPOT, AREA = 0, 1, 2, 3
#: Columns of the packed light table: type, position or direction (3), spot/area axis (3),
#: irradiance factor, colour (3), cos(half cone), smoothstep width, has a smooth edge, grey.
LIGHT_COLUMNS = 15

#: Rows per work item of the parallel loops: small enough to balance the threads when the
#: mask covers only part of the frame, large enough to amortize scheduling.
ROWS_PER_CHUNK = 4

#: Kernels whose parallel loop is over larger work items than rows, with their chunk size
#: (Burley's tiles and STA's groups of rows: one per chunk; the energy's table reads: entries).
CHUNKS = {"burley_kernel": 1, "sta_kernel": 1, "table_lerp": 1 << 14}

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
def _bytes_span(row):
    """``_span`` of a bool row viewed as bytes (uint8), 32 entries at a time where they are all
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


_BACKGROUND = f32(1e9)  # core.base.arrays.BACKGROUND_DEPTH, exactly a float32


@njit(cache=True, inline="always", error_model="numpy")
def _scale_of(z, cam):
    """A pixel's ``core.scene.scene.Camera.pixels_per_unit`` at depth ``z`` (finite, > 0: a pixel that
    takes part), float32 as NumPy computes it; ``cam`` = (1 for orthographic else 0, the
    orthographic pixels per unit or the focal length in pixels). The kernels compute it where
    they need it instead of reading a frame of it."""
    return cam[1] if cam[0] != _ZERO else cam[1] / z


@njit(cache=True, parallel=True, error_model="numpy")
def prepare_pixels(diffuse, albedo, depth, mask, is_ortho, focal, gate, threshold, out, ok, spans, extremes):
    """What SSSS and Burley share before their kernels, in one pass over the frame (the NumPy
    code takes a dozen): ``out`` = albedo x diffuse; with scale = ``core.scene.scene.Camera.
    pixels_per_unit`` of ``depth`` as NumPy computes it in float32 (``is_ortho``: ``focal``, the
    camera's constant; else ``focal`` / depth; 0 where the depth or the quotient is not finite
    or the depth <= 0); ``ok`` = the pixels of ``mask``
    whose diffuse, albedo and depth are finite, with 0 < depth < 1e9 and ``gate`` x scale >
    ``threshold`` (float32 product; ``gate`` +inf: scale > 0, which is what the reference's
    product gives when its factor is beyond float32). Per row y, ``spans[y]`` = (first, last)
    column of ``ok`` ((W, -1) when none) and ``extremes[y]`` the smallest and the largest scale
    there (+inf, 0): the bounding box, ``core.scene.extent.object_extent`` and the reach of a
    footprint in pixels without another pass."""
    h, w = mask.shape
    inf_gate = gate == _INF
    for y in prange(h):
        lo = w
        hi = -1
        least = _INF
        most = _ZERO
        for x in range(w):
            e0 = diffuse[y, x, 0]
            e1 = diffuse[y, x, 1]
            e2 = diffuse[y, x, 2]
            a0 = albedo[y, x, 0]
            a1 = albedo[y, x, 1]
            a2 = albedo[y, x, 2]
            z = depth[y, x]
            out[y, x, 0] = a0 * e0
            out[y, x, 1] = a1 * e1
            out[y, x, 2] = a2 * e2
            if is_ortho:
                s = focal if np.isfinite(z) else _ZERO
            else:
                s = focal / z
                s = s if np.isfinite(s) and z > _ZERO else _ZERO
            take = mask[y, x] and z > _ZERO and z < _BACKGROUND
            take = take and np.isfinite(e0) and np.isfinite(e1) and np.isfinite(e2)
            take = take and np.isfinite(a0) and np.isfinite(a1) and np.isfinite(a2)
            take = take and (s > _ZERO if inf_gate else gate * s > threshold)
            ok[y, x] = take
            if take:
                lo = min(lo, x)
                hi = x
                least = min(least, s)
                most = max(most, s)
        spans[y, 0] = lo
        spans[y, 1] = hi
        extremes[y, 0] = least
        extremes[y, 1] = most


@njit(cache=True, inline="always", error_model="numpy")
def _unit(x, y, z):
    """(x, y, z, |v|) normalized as core.optics.lights.norm does it."""
    length = x * x
    length += y * y
    length += z * z
    length = math.sqrt(length)
    inv = _ONE / (length if length > _TINY else _TINY)
    return x * inv, y * inv, z * inv, length


@njit(cache=True, inline="always", error_model="numpy")
def _sta_half(lx, ly, lz, distortion, nx, ny, nz, vx, vy, vz):
    """(V . normalize(L + d_T N) negated, |L + d_T N|) for one pixel (inlined into the loops,
    which vectorize over the pixels)."""
    ux = distortion * nx
    ux += lx
    uy = distortion * ny
    uy += ly
    uz = distortion * nz
    uz += lz
    length = ux * ux
    length += uy * uy
    length += uz * uz
    length = math.sqrt(length)
    vdot = vx * ux
    vdot += vy * uy
    vdot += vz * uz
    return vdot * (f32(-1.0) / (length if length > _TINY else _TINY)), length


_u64 = np.uint64


@njit(cache=True, error_model="numpy")
def _sta_light(k, lights, pf, p3, m, distortion, t, nxr, nyr, nzr, vxr, vyr, vzr, vd, lens, er):
    """Light ``k`` over the row's span (row ``t`` of the per-thread buffers; the span's first
    pixel at ``p3`` in the flat positions ``pf``): V . normalize(L + d_T N) negated into ``vd``,
    |L + d_T N| into ``lens`` and, for other lights than suns, the irradiance into ``er`` (a
    sun's is ``lights[k, 7]``). One loop per kind of light, so that each vectorizes."""
    kind = int(lights[k, 0])
    if kind == SUN:
        lx = lights[k, 1]
        ly = lights[k, 2]
        lz = lights[k, 3]
        for i in range(m):
            vd[t, i], lens[t, i] = _sta_half(
                lx, ly, lz, distortion, nxr[t, i], nyr[t, i], nzr[t, i], vxr[t, i], vyr[t, i], vzr[t, i]
            )
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
        q = p3 + _u64(3) * _u64(i)  # unsigned: no wrap-around test, the loads stay vector loads
        lx, ly, lz, dist = _unit(cx - pf[q], cy - pf[q + _u64(1)], cz - pf[q + _u64(2)])
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
        er[t, i] = e
        vd[t, i], lens[t, i] = _sta_half(
            lx, ly, lz, distortion, nxr[t, i], nyr[t, i], nzr[t, i], vxr[t, i], vyr[t, i], vzr[t, i]
        )


@njit(cache=True, error_model="numpy")
def _sta_lobe(power, m, t, vd, lens):
    """max(0, vd)^power in place (power 0: 1 where vd > 0), 0 where the direction vanished;
    the common powers without a call to pow, so that the loop vectorizes."""
    if power == _ZERO:
        for i in range(m):
            vd[t, i] = _ONE if vd[t, i] > _ZERO and lens[t, i] > _EPS else _ZERO
    elif power == _TWO:
        for i in range(m):
            v = vd[t, i] if vd[t, i] > _ZERO else _ZERO
            vd[t, i] = v * v if lens[t, i] > _EPS else _ZERO  # x^2 rounded once, as NumPy's square gives it
    elif power == _ONE:
        for i in range(m):
            v = vd[t, i] if vd[t, i] > _ZERO else _ZERO
            vd[t, i] = v if lens[t, i] > _EPS else _ZERO
    else:
        for i in range(m):
            v = vd[t, i] if vd[t, i] > _ZERO else _ZERO
            vd[t, i] = v**power if lens[t, i] > _EPS else _ZERO


@njit(cache=True, error_model="numpy")
def _sta_spans(mask_flat, w, ya, yb, flat, spans):
    """The masked span of rows ``ya``..``yb`` into ``spans`` ((w, w) for a row without any),
    and the zeros of those rows off their span written as contiguous runs (a memset each);
    returns the widest span."""
    widest = 0
    for y in range(ya, yb):
        x0, x1 = _bytes_span(mask_flat[y * w : (y + 1) * w])
        if x0 >= x1:
            x0 = w
            x1 = w
        spans[y, 0] = x0
        spans[y, 1] = x1
        widest = max(widest, x1 - x0)
        row = y * 3 * w
        flat[row : row + 3 * x0] = _ZERO
        flat[row + 3 * x1 : row + 3 * w] = _ZERO
    return widest


@njit(cache=True, error_model="numpy")
def _sta_kinds(lights):
    """(has a grey light, has a coloured one, the first grey light's row or -1) of the light
    table: flags set once before the parallel loop (Numba takes a variable assigned in several
    places of the loop's body for a possible alias, and then marks no argument as not aliasing)."""
    has_grey = False
    has_col = False
    for k in range(lights.shape[0]):
        if lights[k, 14] != _ZERO:
            has_grey = True
        else:
            has_col = True
    first_grey_k = -1
    for k in range(lights.shape[0] - 1, -1, -1):
        if lights[k, 14] != _ZERO:
            first_grey_k = k
    return has_grey, has_col, first_grey_k


@njit(cache=True, error_model="numpy")
def _sta_steps(tab, step):
    """``_sta_table``'s differences along x of the flat medium table ``tab`` (``step`` entries
    per x): ``tab`` one x further minus ``tab``, 0 at the last x."""
    dtab = np.zeros_like(tab)
    for c in range(tab.size - step):
        dtab[c] = tab[c + step] - tab[c]
    return dtab


@njit(cache=True, inline="always", error_model="numpy")
def _sta_pixels(af, nf, pf, tf, mf, p1, p3, m, t, flip, ortho, vx0, vy0, vz0, okr, tr, nxr, nyr, nzr, vxr, vyr, vzr):
    """The pixel's values of a segment of ``m`` pixels (the first at flat pixel ``p1``, flat
    value ``p3``) into row ``t`` of the buffers: 1 in ``okr`` where it is masked and all its
    inputs are finite (else 0), its translucency (the map clipped to [0, 1], flipped with
    ``flip``) in ``tr``, its unit normal and unit vector towards the viewer (``ortho``: the
    view direction (``vx0``, ``vy0``, ``vz0``), else towards that camera position)."""
    for i in range(m):
        q = p3 + _u64(3) * _u64(i)
        a0 = af[q]
        s = a0 + af[q + _u64(1)]
        s += af[q + _u64(2)]
        nx = nf[q]
        ny = nf[q + _u64(1)]
        nz = nf[q + _u64(2)]
        px = pf[q]
        py = pf[q + _u64(1)]
        pz = pf[q + _u64(2)]
        th = tf[p1 + _u64(i)]
        s += nx
        s += ny
        s += nz
        s += px
        s += py
        s += pz
        s += th
        okr[t, i] = _ONE if (mf[p1 + _u64(i)] != 0) & np.isfinite(s) else _ZERO
        th = _clip(th, _ONE)
        tr[t, i] = _ONE - th if flip else th
        nxr[t, i], nyr[t, i], nzr[t, i], _ = _unit(nx, ny, nz)
        if ortho:
            vxr[t, i] = vx0
            vyr[t, i] = vy0
            vzr[t, i] = vz0
        else:
            vxr[t, i], vyr[t, i], vzr[t, i], _ = _unit(vx0 - px, vy0 - py, vz0 - pz)


@njit(cache=True, inline="always", error_model="numpy")
def _sta_add(k, lights, m, t, scale, ambient, first_grey_k, vd, er, grey, c0, c1, c2):
    """Light ``k``'s term over the segment (its lobe in ``vd``, ``_sta_lobe``; a light other
    than a sun: its irradiance in ``er``) added to row ``t`` of the sums: a grey light's (times
    its colour's first channel if that is not 1) to ``grey`` (the first grey light sets it), a
    coloured one's times its colour to ``c0``, ``c1``, ``c2``."""
    sun = int(lights[k, 0]) == SUN
    is_grey = lights[k, 14] != _ZERO
    first_grey = k == first_grey_k
    e_sun_pi = lights[k, 7] * f32(1.0 / math.pi)
    sun_scale = scale * e_sun_pi
    sun_ambient = ambient * e_sun_pi
    col0 = lights[k, 8]
    col1 = lights[k, 9]
    col2 = lights[k, 10]
    tint = is_grey & (col0 != _ONE)
    for i in range(m):
        lobe = vd[t, i]
        if sun:
            lobe *= sun_scale
            if ambient != _ZERO:
                lobe += sun_ambient
        else:
            lobe *= scale
            lobe += ambient
            lobe *= er[t, i] * f32(1.0 / math.pi)
        if is_grey:
            if tint:
                lobe *= col0
            grey[t, i] = lobe if first_grey else grey[t, i] + lobe
        else:
            c0[t, i] += col0 * lobe
            c1[t, i] += col1 * lobe
            c2[t, i] += col2 * lobe


@njit(cache=True, inline="always", error_model="numpy")
def _sta_cells(m, t, nxs, nmu, tr, nxr, nyr, nzr, vxr, vyr, vzr, vd, cell):
    """The medium table's coordinates of the segment's pixels (a loop that vectorizes; the
    table is ``nxs`` x ``nmu`` nodes over sqrt(sqrt(1 - translucency)) and |N . V|): the first of
    each pixel's four nodes into ``cell``, its fractions along x into ``tr`` (in place of the
    translucency) and along the cosine into ``vd``, as ``core.techniques.sta.technique._lookup`` places them."""
    for i in range(m):
        xs = _ONE - tr[t, i]
        sx = math.sqrt(math.sqrt(xs if xs > _ZERO else _ZERO)) * f32(nxs - 1)
        fl = np.floor(sx)
        fl = fl if fl < f32(nxs - 2) else f32(nxs - 2)
        tr[t, i] = sx - fl
        mu = nxr[t, i] * vxr[t, i]
        mu += nyr[t, i] * vyr[t, i]
        mu += nzr[t, i] * vzr[t, i]
        mu = abs(mu)
        sm = (mu if mu < _ONE else _ONE) * f32(nmu - 1)
        fm = np.floor(sm)
        fm = fm if fm < f32(nmu - 2) else f32(nmu - 2)
        vd[t, i] = sm - fm
        cell[t, i] = np.int32(3) * (np.int32(fl) * np.int32(nmu) + np.int32(fm))


@njit(cache=True, inline="always", error_model="numpy")
def _sta_medium_out(af, flat, p3, m, t, has_col, wclip, ib0, ib1, ib2, okr, grey, c0, c1, c2, t0, t1, t2):
    """The medium's products of the segment into ``flat``: the albedo times ``inv_base``
    (``ib0``, ``ib1``, ``ib2``; clipped to [0, 1] with ``wclip``) times the light times the
    table's transmittance (``t0``, ``t1``, ``t2``), 0 where ``okr`` is 0."""
    for i in range(m):
        q = p3 + _u64(3) * _u64(i)
        if has_col:
            l0 = c0[t, i]
            l1 = c1[t, i]
            l2 = c2[t, i]
        else:
            l0 = grey[t, i]
            l1 = l0
            l2 = l0
        w0 = af[q] * ib0
        w1 = af[q + _u64(1)] * ib1
        w2 = af[q + _u64(2)] * ib2
        if wclip:
            w0 = _clip(w0, _ONE)
            w1 = _clip(w1, _ONE)
            w2 = _clip(w2, _ONE)
        o = okr[t, i] != _ZERO
        flat[q] = w0 * l0 * t0[t, i] if o else _ZERO
        flat[q + _u64(1)] = w1 * l1 * t1[t, i] if o else _ZERO
        flat[q + _u64(2)] = w2 * l2 * t2[t, i] if o else _ZERO


@njit(cache=True, inline="always", error_model="numpy")
def _sta_out(af, flat, p3, m, t, has_col, burley, distance, three_d, okr, tr, grey, c0, c1, c2):
    """The products of the segment into ``flat`` without a medium: the albedo times the light
    times the translucency (``burley``: times the transmittance through ``distance`` sqrt(1 -
    t) for the profile lengths ``three_d``), 0 where ``okr`` is 0."""
    for i in range(m):
        q = p3 + _u64(3) * _u64(i)
        th = tr[t, i]
        o = okr[t, i] != _ZERO
        if burley:
            xs = _ONE - th
            xs = distance * math.sqrt(xs if xs > _ZERO else _ZERO)
            for c in range(3):
                if has_col:
                    light = c0[t, i] if c == 0 else c1[t, i] if c == 1 else c2[t, i]
                else:
                    light = grey[t, i]
                if three_d[c] > _ZERO:
                    e3 = _exp(-xs / three_d[c])
                    tm = _QUARTER * (e3 * e3 * e3 + _THREE * e3)
                else:
                    tm = _ONE if xs == _ZERO else _ZERO
                v = af[q + _u64(c)] * light * tm
                flat[q + _u64(c)] = v if o else _ZERO
        elif not has_col:
            g = grey[t, i] * th
            flat[q] = af[q] * g if o else _ZERO
            flat[q + _u64(1)] = af[q + _u64(1)] * g if o else _ZERO
            flat[q + _u64(2)] = af[q + _u64(2)] * g if o else _ZERO
        else:
            flat[q] = af[q] * (c0[t, i] * th) if o else _ZERO
            flat[q + _u64(1)] = af[q + _u64(1)] * (c1[t, i] * th) if o else _ZERO
            flat[q + _u64(2)] = af[q + _u64(2)] * (c2[t, i] * th) if o else _ZERO


#: Rows per work item of ``sta_kernel``.
STA_ROWS = 16
#: Pixels of a row that ``sta_kernel``'s loops take at a time: its row buffers (19 x 4 KB) stay
#: in the second-level cache whatever the frame's width (4K, one thread: 5 % faster than whole rows).
STA_SEGMENT = 1024


@njit(cache=True, inline="always", error_model="numpy")
def _sta_rows(n, w):
    return np.empty((n, w), np.float32)


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
    medium,
    table,
    inv_base,
    wclip,
    out,
):
    """core.techniques.sta.technique.sta's per-pixel arithmetic (its docstring has the formulas) into ``out``
    (H, W, 3), every pixel of which it writes (0 off the mask: ``out`` need not hold zeros);
    ``lights`` is the (L, LIGHT_COLUMNS) table of ``light_table``; with ``burley`` each channel
    is scaled by the transmittance through ``distance`` sqrt(1 - t) for the profile lengths
    ``three_d`` = 3 d_c (0: no scattering);
    with ``medium`` by ``table`` (core.techniques.sta.technique.medium_table: T_c over sqrt(x / D) and the view
    cosine) interpolated as ``core.techniques.sta.technique._lookup`` does, and the albedo times ``inv_base`` (clipped
    to [0, 1] with ``wclip``) in place of the albedo.

    Work items are ``STA_ROWS`` rows: each first writes the zeros of its rows off the mask as
    contiguous runs (``_sta_spans``: a memset each, where per-pixel stores took longer than the
    masked pixels' arithmetic with a quarter of the frame masked). Per row, ``STA_SEGMENT``
    pixels of its masked span at a time, loops that each do one thing for all the pixels (the
    pixel's vectors, ``_sta_pixels``; per light its lobe, ``_sta_light`` and ``_sta_lobe``,
    then its sum, ``_sta_add``; the medium's table coordinates, ``_sta_cells``; its reads, one
    pixel at a time, ``_sta_table``; the products, ``_sta_medium_out`` or ``_sta_out``), with the
    values kept in row buffers, so that every loop but the table's reads vectorizes over the
    pixels. The loops of the helpers marked ``inline="always"`` are inlined into the parallel
    loop's body by Numba, so that they index its arguments as the body itself would. Each work
    item has its row of each buffer (the buffers, allocated before the parallel loop, are
    arguments of its body).

    What lets LLVM vectorize these loops (docs/references.md §11): the (H, W, 3) frames are read
    and written through flat views, the pixel's three values at 3 x + c (a constant stride: a
    3-D index scales x by the array's run-time shape, and the loop then gathers or stays
    scalar); and Numba marks every array the parallel loop's body receives as aliasing no other
    (``noalias``), because the body makes no view of any array and sets no flag in two places:
    without that, a loop writing several buffers needed more run-time overlap checks than LLVM
    makes, and stayed scalar. With both, 1080p, the synthetic benchmark's STA call, one thread:
    28.5 -> 16.0 ms, to the bit the same output."""
    h, w = mask.shape
    n_lights = lights.shape[0]
    has_grey, has_col, first_grey_k = _sta_kinds(lights)
    sum_grey = has_col and (has_grey or medium or burley)
    flat = out.reshape(-1)
    af = albedo.reshape(-1)
    nf = normal.reshape(-1)
    pf = position.reshape(-1)
    tf = thickness.reshape(-1)
    mf = mask.reshape(-1).view(np.uint8)
    tab = table.reshape(-1)
    dtab = _sta_steps(tab, 3 * table.shape[1])
    spans = np.empty((h, 2), np.int64)
    n_items = (h + STA_ROWS - 1) // STA_ROWS
    seg = min(w, STA_SEGMENT)
    # One array per buffer, a row of it per work item, each its own argument of the parallel loop's
    # body (rows of one array would be one object to LLVM, with run-time overlap checks).
    nxr, nyr, nzr = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    vxr, vyr, vzr = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    tr, okr, grey = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    c0, c1, c2 = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    vd, lens, er = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    t0, t1, t2 = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    cell = np.empty((n_items, seg), np.int32)
    vx0 = view[0]
    vy0 = view[1]
    vz0 = view[2]
    ib0 = inv_base[0]
    ib1 = inv_base[1]
    ib2 = inv_base[2]
    nxs = table.shape[0]
    nmu = table.shape[1]
    for item in prange(n_items):
        t = item  # its row of each buffer
        ya = item * STA_ROWS
        yb = min(ya + STA_ROWS, h)
        if _sta_spans(mf, w, ya, yb, flat, spans) == 0:
            continue
        for y in range(ya, yb):
            xe = spans[y, 1]
            for x0 in range(spans[y, 0], xe, STA_SEGMENT):
                m = min(STA_SEGMENT, xe - x0)
                if m <= 0:
                    continue
                # Flat indices, unsigned: no wrap-around tests, so the loops keep vector loads.
                p1 = _u64(y * w + x0)
                p3 = _u64(3) * p1
                _sta_pixels(
                    af, nf, pf, tf, mf, p1, p3, m, t, flip, ortho, vx0, vy0, vz0, okr, tr, nxr, nyr, nzr, vxr, vyr, vzr
                )
                for i in range(m):
                    grey[t, i] = _ZERO
                if has_col:
                    for i in range(m):
                        c0[t, i] = _ZERO
                        c1[t, i] = _ZERO
                        c2[t, i] = _ZERO
                for k in range(n_lights):
                    _sta_light(k, lights, pf, p3, m, distortion, t, nxr, nyr, nzr, vxr, vyr, vzr, vd, lens, er)
                    _sta_lobe(power, m, t, vd, lens)
                    _sta_add(k, lights, m, t, scale, ambient, first_grey_k, vd, er, grey, c0, c1, c2)
                if sum_grey:  # the light per channel into c0, c1, c2
                    for i in range(m):
                        g = grey[t, i] if has_grey else _ZERO
                        c0[t, i] += g
                        c1[t, i] += g
                        c2[t, i] += g
                if medium:
                    # The table's coordinates (a loop that vectorizes), its reads one pixel at a time
                    # (vector gathers were slower), then the products (which vectorize).
                    _sta_cells(m, t, nxs, nmu, tr, nxr, nyr, nzr, vxr, vyr, vzr, vd, cell)
                    _sta_table(tab, dtab, m, t, cell, tr, vd, t0, t1, t2)
                    _sta_medium_out(
                        af, flat, p3, m, t, has_col, wclip, ib0, ib1, ib2, okr, grey, c0, c1, c2, t0, t1, t2
                    )
                else:
                    _sta_out(af, flat, p3, m, t, has_col, burley, distance, three_d, okr, tr, grey, c0, c1, c2)


@njit(cache=True, error_model="numpy")
def _sta_table(tab, dtab, m, t, cell, fxr, fmr, t0, t1, t2):
    """The medium's table (flat, (x, mu, 3)) read bilinearly at each pixel of the row's span
    (the first of its four nodes at ``cell``, fractions ``fxr`` and ``fmr``; row ``t`` of each
    buffer) into ``t0``, ``t1``, ``t2``: ``core.techniques.sta.technique._lookup``'s operations in its order, with
    the differences along x read from ``dtab`` (``tab`` one x further minus ``tab``: the same
    float32 subtractions, made once per node instead of once per pixel)."""
    for i in range(m):
        c = _u64(cell[t, i])
        fx = fxr[t, i]
        fm = fmr[t, i]
        lo0 = tab[c] + fx * dtab[c]
        lo1 = tab[c + _u64(1)] + fx * dtab[c + _u64(1)]
        lo2 = tab[c + _u64(2)] + fx * dtab[c + _u64(2)]
        hi0 = tab[c + _u64(3)] + fx * dtab[c + _u64(3)]
        hi1 = tab[c + _u64(4)] + fx * dtab[c + _u64(4)]
        hi2 = tab[c + _u64(5)] + fx * dtab[c + _u64(5)]
        t0[t, i] = lo0 + fm * (hi0 - lo0)
        t1[t, i] = lo1 + fm * (hi1 - lo1)
        t2[t, i] = lo2 + fm * (hi2 - lo2)


#: Pixels per chunk of a line in SSSS's passes: the chunk's sums (6 x 4 bytes each) and the part
#: of the line its taps read stay in the first-level cache.
SSSS_CHUNK = 256


@njit(cache=True, inline="always", error_model="numpy")
def _ssss_pair(k0, k1, kc, f):
    """A tap's two sample weights (core.techniques.ssss.technique._pass's a0, a1): the interpolation weights 1 - ``f``
    and ``f`` times 1 - the follow-surface blend min(1, |key - ``kc``|) of each sample's key."""
    a0 = _ONE - abs(k0 - kc)
    a0 = (a0 if a0 > _ZERO else _ZERO) * (_ONE - f)
    a1 = _ONE - abs(k1 - kc)
    a1 = (a1 if a1 > _ZERO else _ZERO) * f
    return a0, a1


@njit(cache=True, error_model="numpy")
def _ssss_shifted(lr, lg, lb, lk, kc, fb, c0, ia, ib, d, w0, w1, w2, aw0, aw1, aw2, ag0, ag1, ag2):
    """One tap for the chunk's pixels ``ia``..``ib`` - 1 (from its first pixel ``c0``), all of
    which read the line at their own coordinate plus ``d`` (and the pixel after it), with the
    interpolation weights ``fb``: contiguous loads, no gathers (unsigned indices: Numba adds no
    wrap-around test, so the loads stay contiguous and the loop vectorizes)."""
    b = _u64(c0 + ia + d)
    q = _u64(c0 + ia)
    ua = _u64(ia)
    for t in range(ib - ia):
        ut = _u64(t)
        i = ua + ut
        j = b + ut
        j1 = j + _u64(1)
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
    b = _u64(c0 + ia + d)
    q = _u64(c0 + ia)
    ua = _u64(ia)
    for t in range(ib - ia):
        ut = _u64(t)
        i = ua + ut
        j = b + ut
        j1 = j + _u64(1)
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


@njit(cache=True, inline="always", error_model="numpy")
def _ssss_weighted(n, wsum, d):
    """The surface-weighted result of one channel: the sum ``n`` times wsum / D, D = ``wsum`` +
    ``d`` (core.techniques.ssss.technique._pass; guarded: D may be 0 in a channel whose centre tap weighs 0)."""
    total = wsum + d
    return n * (wsum / total) if total > _ZERO else n


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
    pixels with the same d (the whole chunk, or runs found by a scan: about 90 pixels long on
    the benchmark's spheres, as the footprint varies slowly over a surface) the tap's samples
    are contiguous loads (``_ssss_shifted``), not gathers (measured: a gather per value made
    the pass slower than one pixel at a time). Each pixel's sums are in the taps' order (the
    reference's matrix products sum in their own)."""
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
        aw0[:m] = _ZERO
        aw1[:m] = _ZERO
        aw2[:m] = _ZERO
        ag0[:m] = _ZERO
        ag1[:m] = _ZERO
        ag2[:m] = _ZERO
        if weighted:
            ad0[:m] = _ZERO
            ad1[:m] = _ZERO
            ad2[:m] = _ZERO
            for i in range(m):
                inv[i] = _ONE / la[c0 + i]
        for k in range(offsets.size):
            o = offsets[k]
            w0 = weights[k, 0]
            w1 = weights[k, 1]
            w2 = weights[k, 2]
            for i in range(m):
                x = c0 + i
                pos = sc[_u64(x)] * o
                pos += f32(x)
                pos = _clip(pos, lastf)
                fl = np.floor(pos)
                fb[i] = pos - fl
                db[i] = np.int32(np.int32(fl) - np.int32(x))
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
        q = _u64(c0)
        for i in range(m):
            ui = _u64(i)
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
    kernel spans more than a pixel; scale ``_scale_of`` its depth and ``cam``), both float32 as
    the reference computes them; its key is
    ``depth`` x ``follow`` (the follow-surface factor), +inf for the others. ``offsets`` (n,)
    the non-zero taps in scene units, ``weights`` (n, 3) theirs, ``wsum`` (3,) the sum of all
    weights. Each line is read from planar buffers (R, G, B, key) of the line plus one padding
    pixel (``_ssss_line``). Only the rows box[0]..box[1] - 1 and columns box[2]..box[3] - 1,
    which hold every pixel of ``ok``, are read: outside them the buffers hold (0, 0, 0, +inf),
    the value of a pixel that takes no part. Nothing the size of a frame is allocated.

    With ``surface`` an (H, W) frame, the taps weigh by the surface their pixels cover
    (core.techniques.ssss.technique's "surface" weighting; ``area`` = (far, orthographic, f, cx, cy, min_cos):
    ``surface_area``'s parameters): the row pass computes each pixel's (``_area_at``) and
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
        lk = np.full(w + 1, _INF, np.float32)
        sc = np.zeros(w, np.float32)
        okr = np.zeros(w, np.bool_)
        la = np.ones(w + 1 if weighted else 0, np.float32)
        for x in range(c0, c1):
            s = _scale_of(depth[y, x], cam)
            o = ok[y, x] & (gate * s > half)
            okr[x] = o
            sc[x] = s
            # The row's light, 0 where pixels take no part (a NaN times a zero weight is NaN).
            lr[x] = light[y, x, 0] if o else _ZERO
            lg[x] = light[y, x, 1] if o else _ZERO
            lb[x] = light[y, x, 2] if o else _ZERO
            lk[x] = depth[y, x] * follow if o else _INF
            if weighted:
                la[x] = _area_at(depth, ok, far, ortho, fx, cx, cy, min_cos, y, x)
        x0, x1 = _span(okr[c0:c1])
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
            lines[i, :3, :r0] = _ZERO
            lines[i, 3, :r0] = _INF
            lines[i, :3, r1:] = _ZERO
            lines[i, 3, r1:] = _INF
            lines[i, 4:, :r0] = _ONE
            lines[i, 4:, r1:] = _ONE
        for ya in range(r0, r1, STRIP):
            for i in range(m):
                x = xa + i
                for y in range(ya, min(ya + STRIP, r1)):
                    s = _scale_of(depth[y, x], cam)
                    o = ok[y, x] & (gate * s > half)
                    oks[i, y] = o
                    scs[i, y] = s
                    lines[i, 0, y] = out[y, x, 0] if o else _ZERO
                    lines[i, 1, y] = out[y, x, 1] if o else _ZERO
                    lines[i, 2, y] = out[y, x, 2] if o else _ZERO
                    lines[i, 3, y] = depth[y, x] * follow if o else _INF
                    if weighted:
                        lines[i, 4, y] = surface[y, x] if o else _ONE
        ya = h
        yb = 0
        for i in range(m):
            lo, hi = _span(oks[i, r0:r1])
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


@njit(cache=True, error_model="numpy")
def _burley_positions(xf, yf, s, rc, rsn, tables, g, wl, hl, py0, px0, ph, pw, js, inside):
    """Where the spiral samples of the pixel (``xf``, ``yf``) land, as the reference computes
    it: sample k reads the pixel js[k] of the packed pixels (``burley_pack``, flat: ``ph`` rows
    from ``py0`` of ``pw`` columns from ``px0``), which the reference keeps only if ``inside[k]``
    (the rounded position is on the image). Compiled without fastmath and called from the
    kernels, never from a function with fastmath (Numba compiles a function's callees with its
    flags): the pixels read are the reference's to the bit. The loop vectorizes (no gathers).
    The packed pixels reach beyond every sample (``core.techniques.burley.technique._compiled``); the row and the
    column are clamped to them all the same, so that nothing outside them is ever read."""
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
        row = np.int32(yc) - np.int32(py0)
        row = row if row > np.int32(0) else np.int32(0)
        row = row if row < np.int32(ph) else np.int32(ph - 1)
        col = np.int32(xc) - np.int32(px0)
        col = col if col > np.int32(0) else np.int32(0)
        col = col if col < np.int32(pw) else np.int32(pw - 1)
        js[k] = np.int32(row * np.int32(pw) + col)
        inside[k] = (xc == xs) & (yc == ys)


@njit(cache=True, error_model="numpy", fastmath={"reassoc", "contract"})
def _burley_pixel(packed, area, ids, id_base, q, tables, g, js, inside, k0, k1, k2, sums):
    """The spiral samples of pixel ``q``, read where ``_burley_positions`` put them, summed
    into ``sums`` (num R, G, B, den R, G, B). ``packed`` flat (R, G, B, depth key) per pixel
    of the packed rows (``burley_pack``: 0, 0, 0, +inf where pixels take no part; one 64-byte
    cache line holds a sample's four values), ``q`` and ``js`` index it, and ``area`` (the
    surface each packed pixel covers, which weighs its samples); ``ids`` flat object
    ids of the frame (a packed index plus ``id_base``: the packed rows are whole rows when there
    are ids) or one 0 for none; ``tables[:, g]`` the spiral.

    The loop over the samples vectorizes (a gather per value read), with the weights and sums
    reassociated and fused (``fastmath`` "reassoc" and "contract": the sums in another order,
    one rounding instead of two, within ``core.compute.backend.tolerance``). A sample the reference
    weights by exactly 0 (off the image, off the mask or another object, not in front of the
    pixel) is selected away (its light may be NaN). A sample on something in front of the
    pixel that takes no part (another object, or off the mask: ``area`` holds minus its depth)
    is hidden surface: it counts the pixel's own light at the pixel's depth, with the pixel's
    surface (``core.techniques.burley.technique._gather``)."""
    use_ids = ids.size > 1
    own = ids[q + id_base] if use_ids else ids[0]
    q4 = np.int32(np.int32(4) * np.int32(q))
    zc = packed[np.int32(q4 + np.int32(3))]
    c0 = packed[q4]
    c1 = packed[np.int32(q4 + np.int32(1))]
    c2 = packed[np.int32(q4 + np.int32(2))]
    ac = area[q]
    n0 = _ZERO
    n1 = _ZERO
    n2 = _ZERO
    d0 = _ZERO
    d1 = _ZERO
    d2 = _ZERO
    for k in range(js.size):
        j4 = np.int32(js[k] * np.int32(4))
        zj = packed[np.int32(j4 + np.int32(3))]
        aj = area[js[k]]
        valid = inside[k] & (zj < _INF)
        if use_ids:
            valid &= ids[js[k] + id_base] == own
        # The depth of what the sample lands on: its key where it takes part, else -area.
        zo = zj if zj < _INF else -aj
        hidden = inside[k] & (not valid) & (zo < zc)
        rp = (zc if hidden else zj) - zc
        rp *= rp
        rp += tables[1, g, k]
        rp = math.sqrt(rp)
        ratio = tables[4, g, k] / (rp if rp > _TINY else _TINY)
        ratio *= ac if hidden else aj
        e3 = _exp(rp * k0)
        w0 = (e3 * e3 * e3 + e3) * ratio
        e3 = _exp(rp * k1)
        w1 = (e3 * e3 * e3 + e3) * ratio
        e3 = _exp(rp * k2)
        w2 = (e3 * e3 * e3 + e3) * ratio
        use = valid | hidden
        d0 += w0 if use else _ZERO
        d1 += w1 if use else _ZERO
        d2 += w2 if use else _ZERO
        n0 += w0 * (c0 if hidden else packed[j4]) if use else _ZERO
        n1 += w1 * (c1 if hidden else packed[np.int32(j4 + np.int32(1))]) if use else _ZERO
        n2 += w2 * (c2 if hidden else packed[np.int32(j4 + np.int32(2))]) if use else _ZERO
    sums[0] = n0
    sums[1] = n1
    sums[2] = n2
    sums[3] = d0
    sums[4] = d1
    sums[5] = d2


@njit(cache=True, inline="always", error_model="numpy")
def _camera_point(y, x, z, ortho, f, cx, cy):
    """Pixel (``y``, ``x``) at planar depth ``z`` in camera space, as ``core.optics.energy.view_cosine``
    unprojects it (``f``: pixels per unit for an orthographic camera, the focal length in pixels
    otherwise; ``cx``, ``cy`` the principal point)."""
    if ortho:
        s = 1.0 / f  # the reference multiplies by the unit per pixel
        return (x + 0.5 - cx) * s, (cy - y - 0.5) * s, -z
    return (x + 0.5 - cx) / f * z, (cy - y - 0.5) / f * z, -z


@njit(cache=True, inline="always", error_model="numpy")
def _axis_step(depth, ok, far, y, x, dy, dx, px, py, pz, ortho, f, cx, cy, oy, ox):
    """The difference in camera space from pixel (``y``, ``x``) (at ``px``, ``py``, ``pz``) along
    one image axis (``dy``, ``dx`` the step), as ``core.optics.energy.view_cosine`` takes it: to the next
    pixel of ``ok`` or from the previous one, whichever has the smaller depth step (the next on a
    tie); ``found`` False when neither is on ``ok`` with a depth in (0, ``far``)."""
    h, w = ok.shape
    best = np.inf
    ex = ey = ez = 0.0
    ny, nx = y + dy, x + dx
    if 0 <= ny < h and 0 <= nx < w and ok[ny, nx] and 0.0 < depth[ny, nx] < far:
        qx, qy, qz = _camera_point(
            np.float64(ny + oy), np.float64(nx + ox), np.float64(depth[ny, nx]), ortho, f, cx, cy
        )
        ex, ey, ez = qx - px, qy - py, qz - pz
        best = abs(ez)
    ny, nx = y - dy, x - dx
    if 0 <= ny < h and 0 <= nx < w and ok[ny, nx] and 0.0 < depth[ny, nx] < far:
        qx, qy, qz = _camera_point(
            np.float64(ny + oy), np.float64(nx + ox), np.float64(depth[ny, nx]), ortho, f, cx, cy
        )
        if abs(pz - qz) < best:
            ex, ey, ez = px - qx, py - qy, pz - qz
            best = abs(ez)
    return ex, ey, ez, best < np.inf


@njit(cache=True, parallel=True, error_model="numpy")
def surface_area(depth, ok, far, ortho, f, cx, cy, min_cos, y0, y1, x0, x1, area):
    """``core.optics.surface.surface_area`` over rows ``y0``..``y1`` - 1 and columns ``x0``..``x1`` - 1
    (``area`` holds 1 elsewhere): min(cos a / cos, 1 / ``min_cos``) on the pixels ``ok``, with cos
    the view cosine of ``core.optics.energy.view_cosine`` (in float64: on each axis the difference to a
    neighbour of ``ok`` with the smaller depth step, the normal their cross product; then rounded
    to float32 as the reference's) and a the angle of the pixel's ray to the camera's axis; 1
    where a pixel has no neighbour of ``ok`` on an axis (a cosine of 1). Pixels count when their
    depth is in (0, ``far``) (the reference's valid depth)."""
    for y in prange(y0, y1):
        for x in range(x0, x1):
            area[y, x] = _area_at(depth, ok, far, ortho, f, cx, cy, min_cos, y, x)


@njit(cache=True, inline="always", error_model="numpy")
def _cos_at(depth, ok, far, ortho, f, cx, cy, oy, ox, y, x):
    """``core.optics.energy.view_cosine`` at pixel (``y``, ``x``) of a window whose first pixel is the
    frame's (``oy``, ``ox``): float64 operations in the reference's order (on each axis the
    difference to a neighbour of ``ok`` in the window with the smaller depth step, the next one
    on a tie; the normal their cross product), the clipped cosine rounded to float32; 1 where the
    pixel or a whole axis has no valid pixel (``ok`` with a depth in (0, ``far``))."""
    if not ok[y, x] or not 0.0 < depth[y, x] < far:
        return _ONE
    px, py, pz = _camera_point(np.float64(y + oy), np.float64(x + ox), np.float64(depth[y, x]), ortho, f, cx, cy)
    ax, ay, az, found_x = _axis_step(depth, ok, far, y, x, 0, 1, px, py, pz, ortho, f, cx, cy, oy, ox)
    bx, by, bz, found_y = _axis_step(depth, ok, far, y, x, 1, 0, px, py, pz, ortho, f, cx, cy, oy, ox)
    if not (found_x and found_y):
        return _ONE
    nx = ay * bz - az * by
    ny = az * bx - ax * bz
    nz = ax * by - ay * bx
    vx, vy, vz = (0.0, 0.0, 1.0) if ortho else (-px, -py, -pz)
    den = math.sqrt(nx * nx + ny * ny + nz * nz) * math.sqrt(vx * vx + vy * vy + vz * vz)
    c = abs(nx * vx + ny * vy + nz * vz) / den if den > 0.0 else np.nan
    if c != c:
        return _ONE
    return f32(min(max(c, 0.0), 1.0))


@njit(cache=True, parallel=True, error_model="numpy")
def view_cosine(depth, ok, far, ortho, f, cx, cy, oy, ox, out):
    """``core.optics.energy.view_cosine`` of the window ``depth`` / ``ok`` (``_cos_at``) into ``out``
    (float32, the window's shape), rows in parallel."""
    for y in prange(ok.shape[0]):
        for x in range(ok.shape[1]):
            out[y, x] = _cos_at(depth, ok, far, ortho, f, cx, cy, oy, ox, y, x)


@njit(cache=True, parallel=True, error_model="numpy")
def normal_cosine(normal, ok, rot, ortho, f, cx, cy, oy, ox, out, known):
    """``core.optics.energy.normal_view_cosine`` of the window ``normal`` (float32 (H, W, 3)) / ``ok``
    whose first pixel is the frame's (``oy``, ``ox``), into ``out`` (float32) and ``known``
    (bool), rows in parallel: the reference's float32 operations in its order (the normal over
    its largest component, its camera-space components from ``rot``'s columns (float32 (3, 3)),
    their length, the dot product with the pixel's ray, whose components are rounded to float32
    from float64 as the reference's), so equal to the bit. A normal with a component that is
    not finite, or all 0, is unknown (the reference's NaN)."""
    for y in prange(ok.shape[0]):
        ry = f32((np.float64(y + oy) + 0.5 - cy) / f)
        for x in range(ok.shape[1]):
            out[y, x] = _ONE
            known[y, x] = False
            if not ok[y, x]:
                continue
            a = normal[y, x, 0]
            b = normal[y, x, 1]
            c = normal[y, x, 2]
            if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
                continue
            top = max(abs(a), abs(b), abs(c))
            if top == _ZERO:
                continue
            a = a / top
            b = b / top
            c = c / top
            n0 = a * rot[0, 0] + b * rot[1, 0] + c * rot[2, 0]
            n1 = a * rot[0, 1] + b * rot[1, 1] + c * rot[2, 1]
            n2 = a * rot[0, 2] + b * rot[1, 2] + c * rot[2, 2]
            length = f32(math.sqrt(n0 * n0 + n1 * n1 + n2 * n2))
            if ortho:
                dot = n2
            else:
                rx = f32((cx - np.float64(x + ox) - 0.5) / f)
                dot = (n0 * rx + n1 * ry + n2) / f32(math.sqrt(rx * rx + ry * ry + _ONE))
            cos = abs(dot) / length
            if not (math.isfinite(cos) and length > f32(1e-6)):
                continue
            known[y, x] = True
            out[y, x] = min(cos, _ONE)


@njit(cache=True, inline="always", error_model="numpy")
def _area_at(depth, ok, far, ortho, f, cx, cy, min_cos, y, x):
    """``surface_area``'s value at pixel (``y``, ``x``): 1 where the view cosine is 1, which
    ``_cos_at`` also gives a pixel off ``ok`` or without a valid depth."""
    # The reference rounds the view cosine to float32 before the ratio.
    cos = np.float64(_cos_at(depth, ok, far, ortho, f, cx, cy, 0, 0, y, x))
    if cos >= 1.0:
        return _ONE
    axis = 1.0
    if not ortho:
        u = (x + 0.5 - cx) / f
        v = (cy - y - 0.5) / f
        axis = 1.0 / math.sqrt(1.0 + u * u + v * v)
    return f32(min(axis / max(cos, 1e-30), 1.0 / min_cos))


@njit(cache=True, parallel=True, error_model="numpy")
def burley_pack(light, depth, ok, far, ortho, f, cx, cy, min_cos, y0, x0, packed, packed_area):
    """``packed`` (rows, columns, 4): the rows from y0 and columns from x0 of the frame as (R,
    G, B, depth) where ``ok``, (0, 0, 0, +inf) elsewhere (the reference's packed items: a
    pixel that takes no part gives no light and its weight is 0), so that a sample's four
    values are one aligned 16-byte read; ``packed_area`` (rows, columns) the surface each of
    these pixels covers (``surface_area``, with its parameters ``far`` .. ``min_cos``; computed
    here for the pixels the band's samples reach, not for a frame) where ``ok``, and minus its
    depth elsewhere (-inf where that is not positive): whether a sample landing there is on
    something in front of its pixel (``_burley_pixel``)."""
    for i in prange(packed.shape[0]):
        y = y0 + i
        for j in range(packed.shape[1]):
            x = x0 + j
            o = ok[y, x]
            packed[i, j, 0] = light[y, x, 0] if o else _ZERO
            packed[i, j, 1] = light[y, x, 1] if o else _ZERO
            packed[i, j, 2] = light[y, x, 2] if o else _ZERO
            packed[i, j, 3] = depth[y, x] if o else _INF
            if o:
                packed_area[i, j] = _area_at(depth, ok, far, ortho, f, cx, cy, min_cos, y, x)
            else:
                packed_area[i, j] = -depth[y, x] if depth[y, x] > _ZERO else -_INF


@njit(cache=True, parallel=True, error_model="numpy")
def burley_angles(ok, seed, y0, x0, phi):
    """``phi`` (rows y0.., columns x0..): the spiral's rotation angle of each pixel of ``ok`` (0
    elsewhere), from the integer hash of its flat index and ``seed`` (its low 32 bits,
    0 <= seed < 2^32) that ``core.techniques.burley.technique._rotation`` computes: the same unsigned 64-bit
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
#: (recomputed by its neighbours: 2 radius (1 / BLOCK_ROWS + 1 / TILE_COLS) more work) into a
#: buffer of the tile that the clean-up reads, instead of a whole scattered frame. Measured
#: (CPU time, one thread, 1080p / 4K): 32 x 256 350 / 1610 ms, 64 x 64 370 / 1518 ms, 64 x 128
#: 330 / 1430 ms, 128 x 128 331 / 1431 ms, 16 x 32 385 / 1894 ms.
BLOCK_ROWS = 64
TILE_COLS = 128
#: Within a tile, the pixels are visited in strips of STRIP_COLS columns, each strip from its
#: top row to its bottom one: the samples near a pixel (most of the spiral's: half lie within 1.6
#: d) then land on lines that the pixels just above it read a strip's width earlier, still in
#: the first-level cache, where a tile's whole row of pixels in between would have evicted them
#: once the footprint spans a few dozen pixels. The pixels' results are the same in any order.
#: Measured (CPU time, one thread, the speed benchmark's Burley case alternating 1080p and 4K,
#: fastest of 8, machine loaded): 4K / 1080p 4.42-4.47 row by row, 4.24-4.28 in strips of 16
#: (8: 4.27, 12: 4.24, 32: 4.36); on two threads 4.36-4.43 against 4.27.
STRIP_COLS = 16


@njit(cache=True, error_model="numpy")
def _burley_tile(
    light, packed, packed_area, py0, px0, ok, cam, ids, group, tables, rot_cos, rot_sin, rot_y0, rot_x0, inv3d,
    reach, ya, yb, xa, xb, buf,
):  # fmt: skip
    """core.techniques.burley.technique's gather (the scattered light, before the albedo) of the pixels ``ok`` of
    rows ``ya``..``yb`` - 1 and columns ``xa``..``xb`` - 1 into ``buf`` (3, from (ya, xa)),
    reading the samples from ``packed`` (``burley_pack``, rows from ``py0``, columns from ``px0``);
    ``rot_cos``/``rot_sin`` hold rows from ``rot_y0`` and columns from ``rot_x0``."""
    h, w = ok.shape
    rotate = rot_cos.size > 1
    grouped = group.size > 1
    wl = f32(w - 1)
    hl = f32(h - 1)
    k0 = -inv3d[0]
    k1 = -inv3d[1]
    k2 = -inv3d[2]
    ph = packed.shape[0]
    pw = packed.shape[1]
    flat = packed.reshape(-1)
    area = packed_area.reshape(-1)
    sums = np.empty(6, np.float32)
    js = np.empty(tables.shape[2], np.int32)
    inside = np.empty(tables.shape[2], np.bool_)
    for xs in range(xa, xb, STRIP_COLS):
        for y in range(ya, yb):
            for x in range(xs, min(xs + STRIP_COLS, xb)):
                if not ok[y, x]:
                    continue
                s = _scale_of(flat[np.int32(np.int32(4) * np.int32((y - py0) * pw + x - px0) + np.int32(3))], cam)
                rc = rot_cos[y - rot_y0, x - rot_x0] if rotate else rot_cos[0, 0]
                rsn = rot_sin[y - rot_y0, x - rot_x0] if rotate else rot_sin[0, 0]
                g = group[y, x] if grouped else 0
                _burley_positions(f32(x), f32(y), s, rc, rsn, tables, g, wl, hl, py0, px0, ph, pw, js, inside)
                q = (y - py0) * pw + x - px0
                _burley_pixel(flat, area, ids, py0 * w, q, tables, g, js, inside, k0, k1, k2, sums)
                for c in range(3):
                    den = sums[3 + c]
                    if reach[c] <= 0.0 or reach[c] * np.float64(s) <= 1.0 or den <= _TINY:
                        v = light[y, x, c]
                    else:
                        v = sums[c] / den
                    buf[c, y - ya, x - xa] = v


@njit(cache=True, parallel=True, error_model="numpy")
def burley_kernel(
    light, packed, packed_area, py0, px0, ok, cam, ids, group, tables, rot_cos, rot_sin, rot_y0, rot_x0, inv3d,
    reach, extents, depth, tol, radius, min_px, post, y_lo, y_hi, x_lo, x_hi, out,
):  # fmt: skip
    """core.techniques.burley.technique's gather and clean-up (``_smooth``, when ``radius`` > 0) over the pixels
    ``ok`` of rows ``y_lo``..``y_hi`` - 1 and columns ``x_lo``..``x_hi`` - 1 (which hold all
    those of these rows), times ``post``, into ``out``.

    ``packed`` (``burley_pack``) rows from ``py0`` and columns from ``px0`` (every pixel a sample
    of these pixels reaches; whole rows when there are ids), with ``packed_area`` the surface
    each of them covers over a pixel facing the camera (``core.optics.surface.surface_area``), a factor
    of its samples' weights:
    per pixel (R, G, B, depth) where ``ok``, (0, 0, 0, +inf) elsewhere; ``tables``
    (5, G, n): per object group the spiral's radii, radii squared, cosines, sines and inverse
    pdfs; ``group`` (H, W) each pixel's group, or (1, 1) for one group; ``reach`` (3,) float64,
    16 d_c per channel (0: the channel keeps its light; so does a channel whose reach times the
    pixel's scale is at most one pixel); ``rot_cos``/``rot_sin`` the per-pixel rotation as
    NumPy computed it for rows ``rot_y0``.. and columns ``rot_x0``.. (every pixel of ``ok`` in
    rows y_lo - radius .. y_hi + radius), or
    (1, 1) holding 1 and 0 for none; ``ids`` flat object ids (int32 or int64), or one 0 for
    none.

    A pixel's scale (pixels per scene unit) is ``_scale_of`` its depth and ``cam``.
    The clean-up, per pixel of ``ok`` and channel c whose footprint (scale x min(16 d_c,
    the group's extent ``extents[g]``), float64) spans at least ``min_px``: the float64 mean of
    the scattered light over the (2 ``radius`` + 1)^2 box's pixels of ``ok`` with the same id
    and |``depth`` - own depth| <= ``tol[c]``, in the reference's order (rows, then columns).
    Work items are tiles (``BLOCK_ROWS``, ``TILE_COLS``), gathered with their ``radius`` pixels
    of margin into a buffer of the tile: nothing the size of a frame is allocated."""
    h, w = ok.shape
    r = max(radius, 0)
    n_cols = (x_hi - x_lo + TILE_COLS - 1) // TILE_COLS
    n_rows = (y_hi - y_lo + BLOCK_ROWS - 1) // BLOCK_ROWS
    for tile in prange(n_rows * n_cols):
        y0 = y_lo + (tile // n_cols) * BLOCK_ROWS
        y1 = min(y0 + BLOCK_ROWS, y_hi)
        x0 = x_lo + (tile % n_cols) * TILE_COLS
        x1 = min(x0 + TILE_COLS, x_hi)
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
        buf = np.zeros((3, yb - ya, xb - xa), np.float32)
        _burley_tile(
            light, packed, packed_area, py0, px0, ok, cam, ids, group, tables, rot_cos, rot_sin, rot_y0, rot_x0,
            inv3d, reach, ya, yb, xa, xb, buf,
        )  # fmt: skip
        _burley_clean(
            ok, cam, ids, group, reach, extents, depth, tol, r, min_px, post, buf, ya, xa, y0, y1, x0, x1, out
        )


@njit(cache=True, error_model="numpy")
def _burley_clean(ok, cam, ids, group, reach, extents, depth, tol, r, min_px, post, buf, ya, xa, y0, y1, x0, x1, out):
    """The clean-up (``core.techniques.burley.technique._smooth``) of the tile's rows ``y0``..``y1`` - 1 and columns
    ``x0``..``x1`` - 1 from their gathered light ``buf`` (3, rows from ``ya``, columns from
    ``xa``: the tile and ``r`` pixels of margin), times ``post``, into ``out``: per row and
    channel, a loop over the row's pixels for each neighbour (dy, then dx, the reference's
    order of the float64 sums), which vectorizes; a channel whose footprint is below ``min_px``
    keeps its gathered light."""
    h, w = ok.shape
    grouped = group.size > 1
    use_ids = ids.size > 1
    n = x1 - x0
    total = np.empty(n, np.float64)
    count = np.empty(n, np.float64)
    keep = np.empty(n, np.bool_)
    for y in range(y0, y1):
        for c in range(3):
            any_keep = False
            for i in range(n):
                x = x0 + i
                g = group[y, x] if grouped else 0
                k = r > 0 and ok[y, x] and np.float64(_scale_of(depth[y, x], cam)) * min(reach[c], extents[g]) >= min_px
                keep[i] = k
                any_keep |= k
            if any_keep:
                total[:] = 0.0
                count[:] = 0.0
                tc = tol[c]
                own_z = depth[y]
                own_ids = ids[y * w : (y + 1) * w] if use_ids else ids
                for ny in range(max(y - r, 0), min(y + r + 1, h)):
                    ok_row = ok[ny]
                    z_row = depth[ny]
                    id_row = ids[ny * w : (ny + 1) * w] if use_ids else ids
                    b_row = buf[c, ny - ya]
                    for dx in range(-r, r + 1):
                        lo = max(x0, -dx)
                        hi = min(x1, w - dx)
                        # Unsigned offsets: no wrap-around tests, so that the loop vectorizes.
                        xo = _u64(lo)
                        no = _u64(lo + dx)
                        bo = _u64(lo + dx - xa)
                        io = _u64(lo - x0)
                        for t in range(hi - lo):
                            ut = _u64(t)
                            take = ok_row[no + ut] & (abs(z_row[no + ut] - own_z[xo + ut]) <= tc)
                            if use_ids:
                                take &= id_row[no + ut] == own_ids[xo + ut]
                            total[io + ut] += np.float64(b_row[bo + ut]) if take else 0.0
                            count[io + ut] += 1.0 if take else 0.0
            for i in range(n):
                x = x0 + i
                if ok[y, x]:
                    v = f32(total[i] / max(count[i], 1.0)) if keep[i] else buf[c, y - ya, x - xa]
                    out[y, x, c] = post[y, x, c] * v


@njit(cache=True, inline="always", error_model="numpy")
def _node_below(nodes, v):
    """The index of the last of the ascending ``nodes`` <= ``v`` (``np.searchsorted`` "right"
    minus 1), clipped to 0 .. len(nodes) - 2: the cell of a piecewise-linear table."""
    n = nodes.size
    i = 0
    while i < n and nodes[i] <= v:
        i += 1
    i -= 1
    return min(max(i, 0), n - 2)


@njit(cache=True, parallel=True, error_model="numpy")
def table_lerp(table, rows, cols, rv, cv, r_nan, c_nan, out):
    """``core.optics.energy``'s bilinear table reads (``_lerp2``): per entry q, ``rv[q]`` (NaN read as
    ``r_nan``) and ``cv[q]`` (NaN: ``c_nan``) clipped to the ascending ``rows`` and ``cols``
    nodes of ``table`` (float64), the table interpolated along the columns in both enclosing
    rows, then between the rows, rounded to float32 into ``out[q]``: the reference's float64
    operations in its order (equal to the bit)."""
    for q in prange(out.size):
        out[q] = _lerp_at(table, rows, cols, rv[q], cv[q], r_nan, c_nan)


@njit(cache=True, inline="always", error_model="numpy")
def _lerp_at(table, rows, cols, r, c, r_nan, c_nan):
    """``table_lerp`` of one entry: the float32 of ``table`` (float64) read bilinearly at ``r``
    (NaN read as ``r_nan``) and ``c`` (NaN: ``c_nan``), both clipped to the ascending ``rows`` and
    ``cols`` nodes."""
    i, fr = _cell(rows, r, r_nan)
    j, fc = _cell(cols, c, c_nan)
    return _bilinear(table, i, fr, j, fc)


@njit(cache=True, inline="always", error_model="numpy")
def _cell(nodes, v, v_nan):
    """(the cell, the fraction across it) of ``v`` (NaN read as ``v_nan``) clipped to the ascending
    ``nodes``: the reference's float64 operations (``_node_below``'s cell)."""
    v = v_nan if v != v else v
    v = min(max(v, nodes[0]), nodes[nodes.size - 1])
    i = _node_below(nodes, v)
    return i, (v - nodes[i]) / (nodes[i + 1] - nodes[i])


@njit(cache=True, inline="always", error_model="numpy")
def _bilinear(table, i, fr, j, fc):
    """The float32 of ``table`` between rows ``i`` and ``i`` + 1 (fraction ``fr``) and columns ``j``
    and ``j`` + 1 (``fc``): along the columns first, as the reference."""
    lo = table[i, j] * (1 - fc) + table[i, j + 1] * fc
    hi = table[i + 1, j] * (1 - fc) + table[i + 1, j + 1] * fc
    return f32(lo * (1 - fr) + hi * fr)


@njit(cache=True, parallel=True, error_model="numpy")
def energy_thickness(mb, y0, x0, thickness, as_thickness, distance, least, largest, out):
    """``core.optics.energy.apply_energy``'s slab thickness x (scene units, float64) at each pixel of the
    window ``mb`` (from frame row ``y0`` and column ``x0``; ``thickness`` the frame's baked map,
    ``largest`` the window's largest curvature, float32): the map read as a slab, NaN as 0 and
    clipped to 0..1 (1 - it with ``as_thickness``), D sqrt(1 - tau) with D ``distance``, and where
    the map finds no far side (tau <= 1e-6) at least the sphere's chord 2 / max(largest,
    ``least``), NaN carried through the maxima as NumPy's. The reference's float64 operations in
    its order (equal to the bit); ``out`` is not written off ``mb``."""
    bh, bw = mb.shape
    for i in prange(bh):
        for j in range(bw):
            if not mb[i, j]:
                continue
            tau = np.float64(thickness[y0 + i, x0 + j])
            tau = 0.0 if tau != tau else tau
            tau = min(max(tau, 0.0), 1.0)
            if as_thickness:
                tau = 1.0 - tau
            x = distance * math.sqrt(1.0 - tau)
            if tau <= 1e-6:
                k = np.float64(largest[i, j])
                k = k if k > least or k != k else least
                chord = 2.0 / k
                x = chord if chord > x or chord != chord else x
            out[i, j] = x


@njit(cache=True, parallel=True, error_model="numpy")
def energy_object(
    out, albedo, y0, x0, mb, pre_post, mu, mean_r, mean_g, mean_b, ell, largest, albedos, entry, views, convex,
    curvatures, finite, x, lt, above, below, slab_albedos, logs, unseen, has_unseen,
):  # fmt: skip
    """``core.optics.energy.apply_energy``'s "object" light in place of ``out`` (the frame) at the pixels
    of the window ``mb`` (from frame row ``y0`` and column ``x0``): per channel the entry's gain
    (``entry``: rows the view cosines ``views``, columns ``albedos``; read at ``mu`` and the
    albedo), the convex gain (``convex``: rows ``albedos``, columns ``curvatures``; at the albedo
    and the mean curvature ``mean_*`` times ``ell``) and with ``finite`` the slab's factors
    (``above``, ``below``: rows ``slab_albedos``, columns ``logs``; at the albedo and ``lt``, log2
    of the thickness in mean free paths clipped to the table), the light through the far side
    (with ``has_unseen``: albedo x f_below x ``unseen``) and the convex gain faded towards 1 on a
    shell (x ``largest`` / 2, clipped to 0..1). An empty table (0 rows) reads 1. The albedo is
    ``albedo``'s float32 (squared with ``pre_post``). Each value is the reference's float32 and
    float64 operations in its order (equal to the bit); a cell and its fraction, the same numbers
    for the tables read at the same value on the same nodes, are found once."""
    bh, bw = mb.shape
    slab_last = logs[logs.size - 1]
    for i in prange(bh):
        for j in range(bw):
            if not mb[i, j]:
                continue
            y = y0 + i
            xx = x0 + j
            shell = _ONE
            if finite:
                k = np.float64(largest[i, j])
                k = k if k > 0.0 or k != k else 0.0
                s = x[i, j] * k / 2.0
                if s == s:
                    s = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
                shell = f32(s)
            iv, fv = _cell(views, np.float64(mu[i, j]), 1.0)
            for c in range(3):
                a = albedo[y, xx, c]
                if pre_post:
                    a = a * a
                a64 = np.float64(a)
                light = out[y, xx, c]
                ia, fa = _cell(albedos, a64, albedos[0])
                gain = _bilinear(entry, iv, fv, ia, fa) if entry.shape[0] > 0 else _ONE
                cv = _ONE
                if convex.shape[0] > 0:
                    m = mean_r[i, j] if c == 0 else (mean_g[i, j] if c == 1 else mean_b[i, j])
                    ik, fk = _cell(curvatures, np.float64(m) * ell[c], 0.0)
                    cv = _bilinear(convex, ia, fa, ik, fk)
                if finite:
                    if has_unseen:
                        js, fs = _cell(slab_albedos, a64, slab_albedos[0])
                        jl, fl = _cell(logs, lt[i, j, c], slab_last)
                        f_above = _bilinear(above, js, fs, jl, fl)
                        f_below = _bilinear(below, js, fs, jl, fl)
                        light = light * f_above + a * f_below * unseen[c]
                    cv = _ONE + (cv - _ONE) * shell
                out[y, xx, c] = light * gain * cv


@njit(cache=True, inline="always", error_model="numpy")
def _curvature_unit(normal, position, mask, y, x):
    """(on, unit normal) of a pixel as ``curvature_pixels`` finds them: on the mask, its normal
    and position finite and the normal longer than 0.5."""
    n0 = normal[y, x, 0]
    n1 = normal[y, x, 1]
    n2 = normal[y, x, 2]
    finite = np.isfinite(n0) and np.isfinite(n1) and np.isfinite(n2)
    finite = finite and np.isfinite(position[y, x, 0]) and np.isfinite(position[y, x, 1])
    finite = finite and np.isfinite(position[y, x, 2])
    length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not (mask[y, x] and finite and length > f32(0.5)):
        return False, _ZERO, _ZERO, _ZERO
    return True, n0 / length, n1 / length, n2 / length


@njit(cache=True, parallel=True, error_model="numpy")
def curvature_pixels(normal, position, mask, unit, mean, most, valid, on):
    """``core.optics.energy._curvature_per_pixel`` (the reference: its docstring) of ``normal`` and
    ``position`` (H, W, 3 float32) on ``mask``: ``on`` the pixels of the mask with finite
    inputs and a normal longer than 0.5, ``unit`` their unit normals (0 elsewhere); along each
    image axis the normal curvature between the pixel's neighbours on ``on`` (or the pixel and
    its one neighbour), summed over the axes in float64 into ``mean`` (then divided by their
    number), their largest into ``most``, ``valid`` where there was one. The reference's float32
    operations in its order (its einsum sums the three products one after the other): equal to
    the bit."""
    h, w = mask.shape
    for y in prange(h):
        for x in range(w):
            o, u0, u1, u2 = _curvature_unit(normal, position, mask, y, x)
            on[y, x] = o
            unit[y, x, 0] = u0
            unit[y, x, 1] = u1
            unit[y, x, 2] = u2
    for row in prange(h):
        y = np.int64(row)  # a signed index: the neighbours' are y - 1 and x - 1
        for x in range(w):
            total = 0.0
            count = 0.0
            best = -np.inf
            for axis in range(2):
                dy = np.int64(1 if axis == 0 else 0)
                dx = np.int64(1) - dy
                yb, xb = y + dy, x + dx
                ya, xa = y - dy, x - dx
                ok_n = yb < h and xb < w and on[yb, xb]
                ok_p = ya >= 0 and xa >= 0 and on[ya, xa]
                if not ok_n:
                    yb, xb = y, x
                if not ok_p:
                    ya, xa = y, x
                d0 = position[yb, xb, 0] - position[ya, xa, 0]
                d1 = position[yb, xb, 1] - position[ya, xa, 1]
                d2 = position[yb, xb, 2] - position[ya, xa, 2]
                dd = d0 * d0 + d1 * d1 + d2 * d2
                if on[y, x] and (ok_n or ok_p) and dd > _ZERO:
                    e0 = unit[yb, xb, 0] - unit[ya, xa, 0]
                    e1 = unit[yb, xb, 1] - unit[ya, xa, 1]
                    e2 = unit[yb, xb, 2] - unit[ya, xa, 2]
                    k = (e0 * d0 + e1 * d1 + e2 * d2) / dd
                    total += np.float64(k)
                    count += 1.0
                    best = max(best, np.float64(k))
            v = count > 0.0
            valid[y, x] = v
            mean[y, x] = total / max(count, 1.0) if v else 0.0
            most[y, x] = best if v else 0.0


@njit(cache=True, parallel=True, error_model="numpy")
def box_planes(planes, n, r):
    """The first ``n`` float64 planes of ``planes`` (P, H, W) replaced, each, by its sums over the
    square of half-width ``r`` (zero outside the frame) as ``core.optics.energy._box_sum`` computes them:
    float64 running sums along the columns (strips of ``SPREAD_STRIP``), then along the rows,
    each sum the difference of two of them 2 r + 1 apart (equal to the bit)."""
    h, w = planes.shape[1], planes.shape[2]
    n_col = (w + SPREAD_STRIP - 1) // SPREAD_STRIP
    for item in prange(n * n_col):
        p = item // n_col
        x0 = (item % n_col) * SPREAD_STRIP
        bw = min(x0 + SPREAD_STRIP, w) - x0
        cum = np.zeros((h + 2 * r + 1, SPREAD_STRIP), np.float64)
        for j in range(h):
            for t in range(bw):
                cum[r + 1 + j, t] = cum[r + j, t] + planes[p, j, x0 + t]
        for j in range(r):
            for t in range(bw):
                cum[r + 1 + h + j, t] = cum[r + h + j, t]
        for i in range(h):
            for t in range(bw):
                planes[p, i, x0 + t] = cum[2 * r + 1 + i, t] - cum[i, t]
    for item in prange(n * h):
        p = item // h
        line = planes[p, item % h]
        cum = np.zeros(w + 2 * r + 1, np.float64)
        for j in range(w):
            cum[r + 1 + j] = cum[r + j] + line[j]
        for j in range(r):
            cum[r + 1 + w + j] = cum[r + w + j]
        for i in range(w):
            line[i] = cum[2 * r + 1 + i] - cum[i]


@njit(cache=True, parallel=True, error_model="numpy")
def smooth_curvature(mean, most, valid, on, r, largest, out_mean, out_most):
    """``core.optics.energy._smoothed_curvature``: ``mean`` and, with ``largest``, ``most`` (float64)
    averaged over the pixels of ``valid`` within the square of half-width ``r``, float32 into
    ``out_mean`` and ``out_most`` on ``on`` (0 elsewhere and where no pixel of ``valid`` is near).
    The box sums are the reference's (``_box_sum``): float64 running sums along the columns, then
    along the rows, each difference taken from them as its cumulative sums do (equal to the bit)."""
    h, w = valid.shape
    n = 3 if largest else 2
    planes = np.empty((n, h, w), np.float64)
    for y in prange(h):
        for x in range(w):
            weight = 1.0 if valid[y, x] else 0.0
            planes[0, y, x] = weight
            planes[1, y, x] = mean[y, x] * weight
            if largest:
                planes[2, y, x] = most[y, x] * weight
    box_planes(planes, n, r)
    for y in prange(h):
        for x in range(w):
            near = planes[0, y, x]
            keep = on[y, x] and near > 0.0
            den = max(near, 1.0)
            out_mean[y, x] = f32(planes[1, y, x] / den) if keep else _ZERO
            if largest:
                out_most[y, x] = f32(planes[2, y, x] / den) if keep else _ZERO


#: Columns (vertical passes) or rows (horizontal ones) per work item of ``spread_light``'s box sums.
SPREAD_STRIP = 16


@njit(cache=True, inline="always", error_model="numpy")
def _lamp_at(lights, k, px, py, pz):
    """(lx, ly, lz, E_L) of light ``k`` of ``light_table``'s ``lights`` at the float32 point
    (px, py, pz): ``core.optics.lights.light_at``'s float32 operations in its order, NaN carried through its
    maxima and clip as NumPy's do (a sun's direction and irradiance are its table's)."""
    kind = int(lights[k, 0])
    if kind == SUN:
        return lights[k, 1], lights[k, 2], lights[k, 3], lights[k, 7]
    lx, ly, lz, dist = _unit(lights[k, 1] - px, lights[k, 2] - py, lights[k, 3] - pz)
    r2 = dist * dist
    r2 = r2 if r2 > _R2_MIN or r2 != r2 else _R2_MIN
    if kind == AREA:
        cos_l = -(lx * lights[k, 4] + ly * lights[k, 5] + lz * lights[k, 6])
        cos_l = cos_l if cos_l > _ZERO or cos_l != cos_l else _ZERO
        return lx, ly, lz, lights[k, 7] * cos_l / r2
    e = lights[k, 7] / r2
    if kind == SPOT:
        tc = -(lx * lights[k, 4] + ly * lights[k, 5] + lz * lights[k, 6]) - lights[k, 11]
        cone = _ONE if tc > _ZERO else _ZERO
        if lights[k, 13] != _ZERO:
            u = tc / lights[k, 12]
            u = u if u > _ZERO or u != u else _ZERO
            u = u if u < _ONE or u != u else _ONE
            cone = cone * (u * u * (_THREE - _TWO * u))
        e = e * cone
    return lx, ly, lz, e


@njit(cache=True, inline="always", error_model="numpy")
def _lamp_cosine(lights, k, nx, ny, nz, px, py, pz):
    """max(0, N . L) E_L / pi of light ``k`` at the float32 point (px, py, pz) for the float64
    normal (nx, ny, nz), in float64: ``core.optics.energy.mean_lamp_irradiance``'s per-row term."""
    lx, ly, lz, e = _lamp_at(lights, k, px, py, pz)
    c = nx * np.float64(lx) + ny * np.float64(ly)
    c += nz * np.float64(lz)
    c = 0.0 if c < 0.0 else c  # np.maximum(c, 0): NaN stays NaN
    return c * np.float64(e) / np.pi


@njit(cache=True, parallel=True, error_model="numpy")
def unseen_sums(normal, position, diffuse, albedo, pre_post, mask, lights, lamps, count, light, seen, unseen):
    """Per row of ``mask``, the sums ``core.optics.energy.unseen_irradiance`` takes the means of over the
    pixels whose ``normal`` and ``position`` (H, W, 3 float32) are finite and whose normal is
    longer than 0: their number into ``count`` (H,), their light (``diffuse``, over the albedo at
    least 1e-6 with ``pre_post``) into ``light`` (H, 3), and per light k of ``lights``
    (``light_table``) the unshadowed irradiance over pi on the unit normal into ``seen`` (H, L)
    and, with ``lamps``, on the reversed normal (the opposite surface) into ``unseen`` (H, L).
    Each pixel's terms are the reference's float64 and float32 operations in its order;
    the sums run along the row (the reference sums every pixel at once, pairwise)."""
    h, w = mask.shape
    n_lights = lights.shape[0]
    for y in prange(h):
        n_ok = 0
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for k in range(n_lights):
            seen[y, k] = 0.0
            unseen[y, k] = 0.0
        for x in range(w):
            if not mask[y, x]:
                continue
            nx = np.float64(normal[y, x, 0])
            ny = np.float64(normal[y, x, 1])
            nz = np.float64(normal[y, x, 2])
            length = math.sqrt(nx * nx + ny * ny + nz * nz)
            finite = np.isfinite(nx) and np.isfinite(ny) and np.isfinite(nz)
            p0 = position[y, x, 0]  # tested in its own type, then read as float32 as the reference does
            p1 = position[y, x, 1]
            p2 = position[y, x, 2]
            if not (finite and np.isfinite(p0) and np.isfinite(p1) and np.isfinite(p2) and length > 0.0):
                continue
            px = f32(p0)
            py = f32(p1)
            pz = f32(p2)
            n_ok += 1
            for c in range(3):
                e = diffuse[y, x, c]
                if pre_post:  # e / np.maximum(a, 1e-6): NaN stays NaN
                    a = albedo[y, x, c]
                    e = e / (_EPS if a < _EPS else a)
                if c == 0:
                    s0 += np.float64(e)
                elif c == 1:
                    s1 += np.float64(e)
                else:
                    s2 += np.float64(e)
            inv = length if length > 1e-12 else 1e-12
            nx = nx / inv
            ny = ny / inv
            nz = nz / inv
            for k in range(n_lights):
                seen[y, k] += _lamp_cosine(lights, k, nx, ny, nz, px, py, pz)
            if not lamps:
                continue
            for k in range(n_lights):
                unseen[y, k] += _lamp_cosine(lights, k, -nx, -ny, -nz, px, py, pz)
        count[y] = n_ok
        light[y, 0] = s0
        light[y, 1] = s1
        light[y, 2] = s2


@njit(cache=True, inline="always", error_model="numpy")
def _frame_level(mask, sigma, grid, k, y, x, c, cur, prev, out):
    """``spread_light``'s step at level ``k`` for pixel (``y``, ``x``) and channel ``c`` of the
    level's value ``cur``: where the pixel is on the mask and its width's upper level (the
    reference's searchsorted, clipped to 1.. the last) is ``k``, ``out`` = (1 - w) ``prev`` + w
    ``cur``; then ``prev`` = ``cur``."""
    n_levels = grid.size
    if mask[y, x]:
        s = np.float64(sigma[y, x, c])
        s = _ZERO if s < 0.0 else s
        s = grid[n_levels - 1] if s > grid[n_levels - 1] else s
        hi = 0
        while hi < n_levels and not grid[hi] >= s:
            hi += 1
        hi = min(max(hi, 1), n_levels - 1)
        if hi == k:
            wt = f32((s - grid[k - 1]) / (grid[k] - grid[k - 1]))
            out[y, x, c] = (_ONE - wt) * prev[c, y, x] + wt * cur
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
                mk = _ONE if mask[y, x] else _ZERO
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


def light_table(lights) -> np.ndarray:
    """core.scene.scene.Light list as the STA kernel's (L, LIGHT_COLUMNS) float32 table, each value
    rounded to float32 exactly where ``core.optics.lights.light_at`` rounds it."""
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


# The combined technique's light from behind (``core.techniques.combined.technique``: ``back_light`` and
# ``BackLight.transmitted``, the NumPy reference). Each kernel computes the reference's float32
# and float64 operations in its order, per pixel, on the bounding box of the mask's pixels (the
# region; frame rows and columns from ``y0``, ``x0``): equal to the bit, and check mode compares
# the transmitted light with the reference's with a bound of 0.


@njit(cache=True, inline="always", error_model="numpy")
def _far_pixel(mask, normal, position, y, x):
    """Whether a pixel is one of ``core.techniques.combined.technique.far_side``'s: on the mask, normal and position
    finite."""
    if not mask[y, x]:
        return False
    ok = np.isfinite(normal[y, x, 0]) and np.isfinite(normal[y, x, 1]) and np.isfinite(normal[y, x, 2])
    ok = ok and np.isfinite(position[y, x, 0]) and np.isfinite(position[y, x, 1])
    return ok and np.isfinite(position[y, x, 2])


@njit(cache=True, parallel=True, error_model="numpy")
def back_light_spans(mask, normal, position, thickness, spans):
    """Per row y, the first and last + 1 column of the pixels of ``mask`` whose normal and
    position are finite (``spans[y, 0:2]``: ``core.techniques.combined.technique.far_side``'s pixels) and of those
    whose ``thickness`` is finite (``spans[y, 2:4]``: the pixels the light from behind is
    computed and spread on); (W, 0) where there are none."""
    h, w = mask.shape
    for y in prange(h):
        a0 = w
        a1 = 0
        b0 = w
        b1 = 0
        for x in range(w):
            if not mask[y, x]:
                continue
            if np.isfinite(thickness[y, x]):
                b0 = min(b0, x)
                b1 = x + 1
            if _far_pixel(mask, normal, position, y, x):
                a0 = min(a0, x)
                a1 = x + 1
        spans[y, 0] = a0
        spans[y, 1] = a1
        spans[y, 2] = b0
        spans[y, 3] = b1


@njit(cache=True, inline="always", error_model="numpy")
def _translucency(thickness, y, x, as_thickness):
    """The map's translucency at a pixel, float32 (``core.techniques.combined.technique.back_light``: 0 where not
    finite; 1 - t in the "thickness" convention)."""
    t = thickness[y, x]
    t = t if np.isfinite(t) else _ZERO
    return _ONE - t if as_thickness else t


@njit(cache=True, inline="always", error_model="numpy")
def _far_x(tt, distance, curved, k, kmin):
    """``core.techniques.combined.technique.far_side``'s thickness x (float64) of a pixel of translucency ``tt``:
    D sqrt(1 - tau), and where ``curved`` (the pixel is one of the far side's, with a camera) and
    the map finds no far side (tau <= 1e-6), at least the chord 2 / max(k, ``kmin``) of the
    curvature ``k`` (already max(nan_to_num(largest), 0))."""
    tau = np.float64(tt)
    tau = min(max(tau, 0.0), 1.0)
    x = distance * math.sqrt(1.0 - tau)
    if curved and tau <= 1e-6:
        x = max(x, 2.0 / max(k, kmin))
    return x


@njit(cache=True, inline="always", error_model="numpy")
def _nan_to_num64(v):
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
def _nan_to_num32(v):
    """np.nan_to_num of a float32."""
    if v != v:
        return _ZERO
    if v == _INF:
        return _F32_MAX
    if v == -_INF:
        return -_F32_MAX
    return v


@njit(cache=True, inline="always", error_model="numpy")
def _norm3(a, b, c):
    """np.linalg.norm of a float32 (..., 3) along its last axis: sqrt((a^2 + b^2) + c^2)."""
    return np.sqrt(a * a + b * b + c * c)


@njit(cache=True, inline="always", error_model="numpy")
def _view_vector(px, py, pz, cam):
    """``core.scene.scene.Camera.view_vectors`` at one position (float32): ``cam`` = (1 for
    orthographic else 0, then the camera's position as float32, then -forward as float32)."""
    if cam[0] != _ZERO:
        return cam[4], cam[5], cam[6]
    vx = cam[1] - px
    vy = cam[2] - py
    vz = cam[3] - pz
    n = _norm3(vx, vy, vz)
    n = n if n > f32(1e-20) or n != n else f32(1e-20)
    return vx / n, vy / n, vz / n


@njit(cache=True, parallel=True, error_model="numpy")
def back_light_pixels(
    mask, normal, position, thickness, as_thickness, distance, kmin, walks, cam, largest, cy0, cx0, lights,
    y0, x0, e, lit_rows,
):  # fmt: skip
    """``core.techniques.combined.technique.back_irradiance`` of ``far_side``'s normal on the region (``e``, (rows,
    columns, 3) from frame row ``y0`` and column ``x0``), and per region row whether a pixel there
    is lit (``lit_rows``: irradiance > 0 and a finite map).

    ``largest`` the far side's largest curvature (``core.optics.energy.surface_curvature`` on the box of
    its pixels, from frame row ``cy0`` and column ``cx0``), or (0, 0) without a camera (then no
    chord and the visible normal). With ``walks`` the far normal is the visible one blended
    towards the view vector (``cam``: ``_view_vector``) by s = clip(x k / 2, 0, 1) in float64,
    rounded to float32. ``lights``: ``light_table`` of the lights with energy > 0, in order; per
    light max(-(N . L), 0) E_L / pi (float32: ``core.optics.lights.light_at``'s operations) times its
    colour, summed in float32 from 0."""
    h, w = e.shape[0], e.shape[1]
    ch, cw = largest.shape
    inv_pi = f32(1.0 / math.pi)
    n_lights = lights.shape[0]
    for i in prange(h):
        y = y0 + i
        any_lit = False
        for j in range(w):
            x = x0 + j
            e[i, j, 0] = _ZERO
            e[i, j, 1] = _ZERO
            e[i, j, 2] = _ZERO
            if not _far_pixel(mask, normal, position, y, x):
                continue
            nx = normal[y, x, 0]
            ny = normal[y, x, 1]
            nz = normal[y, x, 2]
            px = position[y, x, 0]
            py = position[y, x, 1]
            pz = position[y, x, 2]
            cy = y - cy0
            cx = x - cx0
            if 0 <= cy < ch and 0 <= cx < cw:  # the far side's pixels with a camera
                k = max(_nan_to_num64(np.float64(largest[cy, cx])), 0.0)
                xs = _far_x(_translucency(thickness, y, x, as_thickness), distance, True, k, kmin)
                if walks:
                    s = min(max(xs * k / 2.0, 0.0), 1.0)
                    length = _norm3(nx, ny, nz)
                    length = length if length > f32(1e-20) or length != length else f32(1e-20)
                    ux = _nan_to_num32(nx / length)
                    uy = _nan_to_num32(ny / length)
                    uz = _nan_to_num32(nz / length)
                    vx, vy, vz = _view_vector(px, py, pz, cam)
                    nx = f32((1.0 - s) * np.float64(ux) + s * np.float64(vx))
                    ny = f32((1.0 - s) * np.float64(uy) + s * np.float64(vy))
                    nz = f32((1.0 - s) * np.float64(uz) + s * np.float64(vz))
                    if not (np.isfinite(nx) and np.isfinite(ny) and np.isfinite(nz)):
                        continue
            nx, ny, nz, _ = _unit(nx, ny, nz)
            a0 = _ZERO
            a1 = _ZERO
            a2 = _ZERO
            for q in range(n_lights):
                lx, ly, lz, el = _lamp_at(lights, q, px, py, pz)
                back = -(nx * lx + ny * ly + nz * lz)
                back = back if back > _ZERO or back != back else _ZERO
                back = back * el * inv_pi
                a0 += back * lights[q, 8]
                a1 += back * lights[q, 9]
                a2 += back * lights[q, 10]
            e[i, j, 0] = a0
            e[i, j, 1] = a1
            e[i, j, 2] = a2
            if np.isfinite(thickness[y, x]):
                most = a0 if a0 > a1 or a0 != a0 else a1
                most = most if most > a2 or most != most else a2
                any_lit |= most > _ZERO
        lit_rows[i] = any_lit


@njit(cache=True, inline="always", error_model="numpy")
def _below(v, xp):
    """The node of the ascending ``xp`` below ``v`` (xp[i] <= v < xp[i + 1], by bisection as
    np.interp finds it) for xp[0] <= v < xp[-1]; the same for any of ``xp``'s first nodes that
    still hold ``v`` below their last."""
    lo = 0
    hi = xp.size - 1
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if xp[mid] <= v:
            lo = mid
        else:
            hi = mid
    return lo


@njit(cache=True, inline="always", error_model="numpy")
def _interp(v, xp, fp, right, lo):
    """np.interp of one float64 value (left: ``fp[0]``) with NumPy's operations, ``lo`` the node
    below ``v`` (``_below``; read only for xp[0] <= v < xp[-1]): the value at a node itself, else
    slope x (v - node) + value, and the same from the node above where that is NaN."""
    n = xp.size
    if v != v:
        return v
    if v < xp[0]:
        return fp[0]
    if v > xp[n - 1]:
        return right
    if v == xp[n - 1]:
        return fp[n - 1]
    if xp[lo] == v:
        return fp[lo]
    slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo])
    r = slope * (v - xp[lo]) + fp[lo]
    if r != r:
        r = slope * (v - xp[lo + 1]) + fp[lo + 1]
        if r != r and fp[lo] == fp[lo + 1]:
            r = fp[lo]
    return r


@njit(cache=True, inline="always", error_model="numpy")
def _entry_lerp(tau, m, grid, columns, c, nodes, first):
    """``core.optics.transmittance._interp_entry`` / ``_interp_rough`` of one pixel: the columns
    ``columns[c, first + g]`` (one per entry cosine ``grid[g]``) read at ``tau``, then linear in
    ``m`` between the two enclosing entries (the last entry's value where none encloses it)."""
    n = grid.size
    lo = _below(tau, nodes)
    for g in range(n - 1):
        a = grid[g]
        b = grid[g + 1]
        if m >= a and m < b:
            wt = (m - a) / (b - a)
            va = _interp(tau, nodes, columns[c, first + g], 0.0, lo)
            vb = _interp(tau, nodes, columns[c, first + g + 1], 0.0, lo)
            return (1.0 - wt) * va + wt * vb
    return _interp(tau, nodes, columns[c, first + n - 1], 0.0, lo)


#: How ``transmit_pixels`` reads the transmittance: a random walk, the Skin method's walk, and
#: Christensen-Burley's disk probes.
WALK, SKIN, DISK = 0, 1, 2


@njit(cache=True, inline="always", error_model="numpy")
def _transmittance(kind, x, mu_v, ior2, ell, grid, columns, nodes, c):
    """``core.optics.medium.slab_transmittance_rgb`` of one pixel and channel, float64 (``kind``
    ``WALK``, ``SKIN`` or ``DISK``; ``ell`` the channel's length: the walk's reduced mean free
    path or Burley's d)."""
    if ell <= 0.0:
        return 1.0 if x == 0.0 else 0.0
    if kind == DISK:
        v = x / ell
        return _interp(v, nodes, columns[c, 0], 0.0, _below(v, nodes))
    tau = x / ell
    if kind == SKIN:
        m = min(max(mu_v, grid[0]), 1.0)
        rough = _entry_lerp(tau, m, grid, columns, c, nodes, 0)
        return (1.0 - 0.5) * rough + 0.5 * _interp(tau, nodes, columns[c, grid.size], 0.0, _below(tau, nodes))
    mu0 = math.sqrt(min(max(1.0 - (1.0 - mu_v * mu_v) / ior2, 0.0), 1.0))
    mu0 = min(max(mu0, grid[0]), 1.0)
    return _entry_lerp(tau, mu0, grid, columns, c, nodes, 0)


@njit(cache=True, inline="always", error_model="numpy")
def _pixel_x(mask, normal, position, thickness, as_thickness, distance, kmin, largest, cy0, cx0, y, x):
    """(x, k): ``core.techniques.combined.technique.far_side``'s thickness of a pixel and its curvature (float64; the
    chord and k only for a pixel of the far side, the mask's pixels with a finite normal and
    position, within ``largest``'s box: with a camera)."""
    ch, cw = largest.shape
    cy = y - cy0
    cx = x - cx0
    k = 0.0
    curved = False
    if 0 <= cy < ch and 0 <= cx < cw and _far_pixel(mask, normal, position, y, x):
        curved = True
        k = max(_nan_to_num64(np.float64(largest[cy, cx])), 0.0)
    return _far_x(_translucency(thickness, y, x, as_thickness), distance, curved, k, kmin), k


@njit(cache=True, inline="always", error_model="numpy")
def _view_cos(normal, position, y, x, cam):
    """``core.techniques.combined.technique.view_cosine`` of one pixel: |nan_to_num(N / |N| . V)|, float32."""
    nx = normal[y, x, 0]
    ny = normal[y, x, 1]
    nz = normal[y, x, 2]
    length = _norm3(nx, ny, nz)
    length = length if length > f32(1e-20) or length != length else f32(1e-20)
    vx, vy, vz = _view_vector(position[y, x, 0], position[y, x, 1], position[y, x, 2], cam)
    return abs(_nan_to_num32(nx / length * vx + ny / length * vy + nz / length * vz))


_ROOT2 = math.sqrt(2.0)


@njit(cache=True, inline="always", error_model="numpy")
def _spread_width(kind, xs, spread_len, spread_counts, spread_nodes, spread_values, c):
    """``core.techniques.combined.technique.spread_sigma`` of channel ``c`` through thickness ``xs``, float32 (NaN where
    the walk's table ends; 0 for a length of 0)."""
    d = spread_len[c]
    n = spread_counts[c]
    if d <= 0.0 or n == 0:
        return _ZERO
    v = xs / d
    if kind == DISK:
        return f32(math.sqrt(_interp(v, spread_nodes, spread_values[c], 0.0, _below(v, spread_nodes))) * d / _ROOT2)
    return f32(_interp(v, spread_nodes[:n], spread_values[c, :n], np.nan, _below(v, spread_nodes)) * d / _ROOT2)


@njit(cache=True, inline="always", error_model="numpy")
def _pixel_scale(depth, y, x, ortho, focal):
    """``core.scene.scene.Camera.pixels_per_unit`` of a pixel, float32: ``focal`` / z, or ``focal`` for an
    orthographic camera; 0 where that is not finite or z <= 0 (orthographic: z not finite)."""
    z = depth[y, x]
    if ortho:
        return focal if np.isfinite(z) else _ZERO
    scale = focal / z
    return scale if np.isfinite(scale) and not z <= _ZERO else _ZERO


@njit(cache=True, parallel=True, error_model="numpy")
def transmit_pixels(
    e, mask, normal, position, thickness, as_thickness, distance, kmin, largest, cy0, cx0, y0, x0, view, cam,
    kind, ior2, ell, grid, columns, nodes, spread, spread_len, spread_counts, spread_nodes, spread_values, ids,
    part_ids, depth, ortho, focal, light, part_rows,
):  # fmt: skip
    """``core.techniques.combined.technique.BackLight.transmitted`` before its spread: ``light`` = ``e`` x T_c(x) on the
    lit pixels of the region (irradiance > 0, finite map), 0 elsewhere, float32 (T_c
    ``_transmittance``, x ``_pixel_x``; with ``view`` the view cosine of the visible normal
    (``_view_cos``), else 1). ``light`` may be ``e`` itself (each pixel reads its own first).

    With ``spread`` (a Depth pass and a camera), per pixel of the mask with a finite map: its
    part (``part_ids``, ascending, holding the pixel's object id ``ids``; a single part when
    ``ids`` is (1, 1)) and its spread's width before the pixel's scale (``_spread_width``:
    ``core.techniques.combined.technique.spread_sigma``'s value, NaN where the walk's table ends, where the reference
    puts the part's largest) and that scale (``_pixel_scale`` of ``depth``, ``ortho``,
    ``focal``), into per region row and part (``part_rows``): the first and last + 1 region
    column of the part's pixels; per channel the largest width (at least 0), the smallest and
    the largest width times the scale where the width is not NaN (+inf and 0 without a pixel),
    and the smallest and the largest scale where it is NaN (+inf and 0 without a pixel), from
    which ``band_sigma``'s widths' range per row follows once the part's largest is known,
    without a frame of widths."""
    h, w = light.shape[0], light.shape[1]
    one_part = ids.shape[0] == 1 and ids.shape[1] == 1 and part_ids.size == 1
    n_parts = part_ids.size if spread else 0
    for i in prange(h):
        y = y0 + i
        for p in range(n_parts):
            part_rows[i, p, 0] = w
            part_rows[i, p, 1] = 0
            for c in range(3):
                part_rows[i, p, 2 + c] = 0.0
                part_rows[i, p, 5 + c] = np.inf
                part_rows[i, p, 8 + c] = 0.0
                part_rows[i, p, 11 + c] = np.inf
                part_rows[i, p, 14 + c] = 0.0
        for j in range(w):
            x = x0 + j
            a0 = e[i, j, 0]
            a1 = e[i, j, 1]
            a2 = e[i, j, 2]
            finite = np.isfinite(thickness[y, x])
            most = a0 if a0 > a1 or a0 != a0 else a1
            most = most if most > a2 or most != most else a2
            lit = finite and most > _ZERO
            in_mask = spread and finite and mask[y, x]
            if not lit:
                light[i, j, 0] = _ZERO
                light[i, j, 1] = _ZERO
                light[i, j, 2] = _ZERO
            if not (lit or in_mask):
                continue
            xs, _ = _pixel_x(mask, normal, position, thickness, as_thickness, distance, kmin, largest, cy0, cx0, y, x)
            if lit:
                mu_v = 1.0
                if view:
                    mu_v = min(max(np.float64(_view_cos(normal, position, y, x, cam)), 0.0), 1.0)
                # One loop over the channels, not three calls: each call of an inlined function is
                # compiled anew (three took its first compile from 18 to 64 s).
                for c in range(3):
                    light[i, j, c] = e[i, j, c] * f32(
                        _transmittance(kind, xs, mu_v, ior2, ell[c], grid, columns, nodes, c)
                    )
            if not in_mask:
                continue
            p = 0
            if not one_part:
                v = ids[y, x]
                p = np.searchsorted(part_ids, v)
                if p >= part_ids.size or part_ids[p] != v:
                    continue
            part_rows[i, p, 0] = min(part_rows[i, p, 0], j)
            part_rows[i, p, 1] = j + 1
            scale = _pixel_scale(depth, y, x, ortho, focal)
            for c in range(3):
                s = _spread_width(kind, xs, spread_len, spread_counts, spread_nodes, spread_values, c)
                if s == s:
                    part_rows[i, p, 2 + c] = max(part_rows[i, p, 2 + c], np.float64(s))
                    s = s * scale
                    part_rows[i, p, 5 + c] = min(part_rows[i, p, 5 + c], np.float64(s))
                    part_rows[i, p, 8 + c] = max(part_rows[i, p, 8 + c], np.float64(s))
                else:
                    part_rows[i, p, 11 + c] = min(part_rows[i, p, 11 + c], np.float64(scale))
                    part_rows[i, p, 14 + c] = max(part_rows[i, p, 14 + c], np.float64(scale))


@njit(cache=True, inline="always", error_model="numpy")
def _in_part(mask, thickness, ids, part_ids, p, one_part, y, x):
    """Whether frame pixel (``y``, ``x``) is one of part ``p``'s (the mask's pixels with a finite
    map and, with ids, the part's object id)."""
    if not (mask[y, x] and np.isfinite(thickness[y, x])):
        return False
    return one_part or ids[y, x] == part_ids[p]


@njit(cache=True, parallel=True, error_model="numpy")
def band_sigma(
    mask, normal, position, thickness, as_thickness, distance, kmin, largest, cy0, cx0, y0, x0, kind, spread_len,
    spread_counts, spread_nodes, spread_values, ids, part_ids, p, one_part, depth, ortho, focal, fill, part, b0, b1,
    sig,
):  # fmt: skip
    """The spread's width in pixels of part ``p``'s pixels (``_in_part``) in region rows ``b0``..
    ``b1`` - 1 and columns ``part[2]``..``part[3]`` - 1, into ``sig`` (band rows from ``b0``,
    region columns, 3): ``transmit_pixels``' width before the scale (``_spread_width``), its NaN
    replaced by ``fill`` (float32, per channel), times the pixel's scale (``_pixel_scale``)."""
    for i in prange(b0, b1):
        y = y0 + i
        for j in range(part[2], part[3]):
            x = x0 + j
            if not _in_part(mask, thickness, ids, part_ids, p, one_part, y, x):
                continue
            xs, _ = _pixel_x(mask, normal, position, thickness, as_thickness, distance, kmin, largest, cy0, cx0, y, x)
            scale = _pixel_scale(depth, y, x, ortho, focal)
            for c in range(3):
                s = _spread_width(kind, xs, spread_len, spread_counts, spread_nodes, spread_values, c)
                s = fill[c] if s != s else s
                sig[i - b0, j, c] = s * scale


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


@njit(cache=True, parallel=True, error_model="numpy")
def part_pixels(mask, thickness, ids, part_ids, p, one_part, y0, x0, part, on):
    """``on`` (part rows, part columns): 1 at part ``p``'s pixels (``_in_part``), else 0."""
    for i in prange(part[0], part[1]):
        for j in range(part[2], part[3]):
            inside = _in_part(mask, thickness, ids, part_ids, p, one_part, y0 + i, x0 + j)
            on[i - part[0], j - part[2]] = 1 if inside else 0


#: Columns of a part ``spread_band``'s vertical passes sum together: its running sums go down the
#: columns one row (tens of kB apart) after the other, so a wide strip does more per memory page
#: touched. Measured (``benchmarks.speed``'s profile, full screen, before the passes went in
#: bands): 16 columns 211 / 1201 ms at 1080p / 4K (5.7x), 64: 166 / 839, 128: 146 / 632 (4.3x),
#: 256: 130 / 695 (a strip of 2160 rows no longer fits the 2 MB second-level cache).
PART_STRIP = 128

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
                mk = _ONE if row[xs + t - part[2]] != 0 else _ZERO
                x[t] = light[t_row - l0, xs + t, q] * mk if q < 3 else mk
        else:
            for t in range(bw):
                x[t] = _ZERO
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
                    out[i - b0, j, c] = (_ONE - wt) * cur


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
                out[i - b0, j, c] = (_ONE - wt) * light[i - l0, j, c]
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
                        line[j - left, 4 * g + q] = planes[q, i0 + g - b0, j - part[2]] if needed[k, q] else _ZERO
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
                            v = _ZERO
                            if i < box[1] and j < box[3] and part[0] <= i < part[1] and part[2] <= j < part[3]:
                                mk = _ONE if on[i - o0, j - part[2]] != 0 else _ZERO
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
                        out[i, j, c] = (_ONE - wt) * cur
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


@njit(cache=True, parallel=True, error_model="numpy")
def part_results(light, on, part, out):
    """The end of a part's spread: its pixels of ``light`` take their results from ``out``."""
    for i in prange(part[0], part[1]):
        for j in range(part[2], part[3]):
            if on[i - part[0], j - part[2]] != 0:
                for c in range(3):
                    light[i, j, c] = out[i, j, c]


@njit(cache=True, inline="always", error_model="numpy")
def _exit_weight(a, pre_post, walks, base):
    """``core.optics.medium.exit_weight`` of one albedo value (float32)."""
    if pre_post:
        a = a * a
    if not walks:
        return a
    if base > _ZERO:
        a = a / (base if base > f32(1e-6) else f32(1e-6))
    else:
        a = _ZERO
    a = a if a > _ZERO or a != a else _ZERO
    return a if a < _ONE or a != a else _ONE


@njit(cache=True, inline="always", error_model="numpy")
def _finished(v, albedo, y, x, c, pre_post, walks, base, has_weight, scale, scaled):
    """``finish_light``'s value of light ``v`` at frame pixel (``y``, ``x``) and channel ``c``: times
    the exit weight (with ``has_weight``) and, where ``scaled``, times ``scale[c]``."""
    if has_weight:
        v = v * _exit_weight(albedo[y, x, c], pre_post, walks, base[c])
    if scaled:
        v = v * scale[c]
    return v


@njit(cache=True, inline="always", error_model="numpy")
def _finish_dark(albedo, y, x, pre_post, walks, base, scale, scaled, add, out):
    """``finish_light`` at a pixel outside the region (with a weight): 0 x the weight changes
    ``out`` only where the weight is not finite (NaN)."""
    for c in range(3):
        a = albedo[y, x, c]
        if np.isfinite(a) and (walks or np.isfinite(a * a)):
            continue  # 0 x a finite weight: nothing changes
        v = _finished(_ZERO, albedo, y, x, c, pre_post, walks, base, True, scale, scaled)
        out[y, x, c] = out[y, x, c] + v if add else v


@njit(cache=True, parallel=True, error_model="numpy")
def finish_light(light, y0, x0, albedo, pre_post, walks, base, has_weight, scale, scaled, add, out):
    """``core.techniques.combined.technique.BackLight.transmitted``'s last steps into the frame ``out``: the light
    (``light``, the region from frame row ``y0`` and column ``x0``; 0 elsewhere) times the exit
    weight (with ``has_weight``: ``_exit_weight`` of ``albedo``) and, where ``scaled``, times
    ``scale``; written (``out`` holds zeros) or, with ``add``, added to ``out``. Outside the
    region 0 x weight changes nothing but where the weight is not finite (NaN)."""
    h, w = out.shape[0], out.shape[1]
    rh, rw = light.shape[0], light.shape[1]
    for y in prange(h):
        inside_rows = y0 <= y < y0 + rh
        if inside_rows:
            for x in range(x0, x0 + rw):
                for c in range(3):
                    v = light[y - y0, x - x0, c]
                    v = _finished(v, albedo, y, x, c, pre_post, walks, base, has_weight, scale, scaled)
                    out[y, x, c] = out[y, x, c] + v if add else v
        if not has_weight:
            continue
        for x in range(w):
            if inside_rows and x0 <= x < x0 + rw:
                continue
            _finish_dark(albedo, y, x, pre_post, walks, base, scale, scaled, add, out)


@njit(cache=True, inline="always", error_model="numpy")
def _owned(mask, thickness, ids, part_ids, owned, one_part, y, x):
    """Whether frame pixel (``y``, ``x``) is one of a part whose light spreads (``owned[p]``; its
    part as ``transmit_pixels`` finds it)."""
    if not (mask[y, x] and np.isfinite(thickness[y, x])):
        return False
    if one_part:
        return owned[0]
    v = ids[y, x]
    p = np.searchsorted(part_ids, v)
    return p < part_ids.size and part_ids[p] == v and owned[p]


@njit(cache=True, parallel=True, error_model="numpy")
def finish_band(
    light, fy0, x0, mode, on, ox0, owned, mask, thickness, ids, part_ids, one_part, albedo, pre_post, walks, base,
    has_weight, scale, scaled, add, out,
):  # fmt: skip
    """``finish_light`` of a band of the region's rows (``light``: frame rows from ``fy0``, the
    region's columns from ``x0``), at its pixels of ``mode`` 0: all; 1: where ``on`` (the band's
    rows, region columns from ``ox0``) is not 0; 2: those of no part whose light spreads
    (``_owned``). The pixels outside the region: ``finish_rest``."""
    rows, rw = light.shape[0], light.shape[1]
    for i in prange(rows):
        y = fy0 + i
        for jj in range(rw):
            x = x0 + jj
            if mode == 1:
                k = jj - ox0
                if k < 0 or k >= on.shape[1] or on[i, k] == 0:
                    continue
            elif mode == 2 and _owned(mask, thickness, ids, part_ids, owned, one_part, y, x):
                continue
            for c in range(3):
                v = _finished(light[i, jj, c], albedo, y, x, c, pre_post, walks, base, has_weight, scale, scaled)
                out[y, x, c] = out[y, x, c] + v if add else v


@njit(cache=True, parallel=True, error_model="numpy")
def finish_rest(y0, rh, x0, rw, albedo, pre_post, walks, base, scale, scaled, add, out):
    """``finish_light`` at the pixels outside the region (rows ``y0``.. and columns ``x0``.., ``rh``
    x ``rw``), with a weight (without one nothing changes there)."""
    h, w = out.shape[0], out.shape[1]
    for y in prange(h):
        inside_rows = y0 <= y < y0 + rh
        for x in range(w):
            if inside_rows and x0 <= x < x0 + rw:
                continue
            _finish_dark(albedo, y, x, pre_post, walks, base, scale, scaled, add, out)


@njit(cache=True, inline="always", error_model="numpy")
def _unit_row(normal, position, mask, y0, x0, w, n, xa, xb, ons, units):
    """``_curvature_unit`` of window row ``n``'s columns ``xa`` - 1..``xb`` (within the window's
    ``w``) into slot n mod 3 of ``ons`` and ``units`` (column j at j - ``xa`` + 1)."""
    slot = n % 3
    for j in range(max(xa - 1, 0), min(xb + 1, w)):
        on, u0, u1, u2 = _curvature_unit(normal, position, mask, y0 + n, x0 + j)
        ons[slot, j - xa + 1] = on
        units[slot, j - xa + 1, 0] = u0
        units[slot, j - xa + 1, 1] = u1
        units[slot, j - xa + 1, 2] = u2


@njit(cache=True, inline="always", error_model="numpy")
def _plane_of_units(position, y0, x0, h, w, i, j, xa, ons, units):
    """``curvature_pixels``' largest curvature and validity at pixel (``i``, ``j``) of the window
    (``h``, ``w``) from frame row ``y0`` and column ``x0``, without its frames of unit normals and
    mean curvature: (1 where valid else 0, the largest times that: ``smooth_curvature``'s planes).
    The same float32 and float64 operations in the same order, the unit normals of rows i - 1..
    i + 1 those ``_unit_row`` keeps; neighbours outside the window count as off the mask, as on
    the window the reference is given."""
    k = j - xa + 1
    rs = i % 3
    on = ons[rs, k]
    u0 = units[rs, k, 0]
    u1 = units[rs, k, 1]
    u2 = units[rs, k, 2]
    count = 0.0
    best = -np.inf
    for axis in range(2):
        di = np.int64(1 if axis == 0 else 0)
        dj = np.int64(1) - di
        ib, jb = i + di, j + dj
        ia, ja = i - di, j - dj
        ok_n = False
        b0 = b1 = b2 = _ZERO
        if ib < h and jb < w:
            sb, kb = ib % 3, k + dj
            ok_n, b0, b1, b2 = ons[sb, kb], units[sb, kb, 0], units[sb, kb, 1], units[sb, kb, 2]
        ok_p = False
        a0 = a1 = a2 = _ZERO
        if ia >= 0 and ja >= 0:
            sa, ka = ia % 3, k - dj
            ok_p, a0, a1, a2 = ons[sa, ka], units[sa, ka, 0], units[sa, ka, 1], units[sa, ka, 2]
        if not ok_n:
            ib, jb, b0, b1, b2 = i, j, u0, u1, u2
        if not ok_p:
            ia, ja, a0, a1, a2 = i, j, u0, u1, u2
        d0 = position[y0 + ib, x0 + jb, 0] - position[y0 + ia, x0 + ja, 0]
        d1 = position[y0 + ib, x0 + jb, 1] - position[y0 + ia, x0 + ja, 1]
        d2 = position[y0 + ib, x0 + jb, 2] - position[y0 + ia, x0 + ja, 2]
        dd = d0 * d0 + d1 * d1 + d2 * d2
        if on and (ok_n or ok_p) and dd > _ZERO:
            e0 = b0 - a0
            e1 = b1 - a1
            e2 = b2 - a2
            k2 = (e0 * d0 + e1 * d1 + e2 * d2) / dd
            count += 1.0
            best = max(best, np.float64(k2))
    v = count > 0.0
    weight = 1.0 if v else 0.0
    return weight, (best if v else 0.0) * weight


@njit(cache=True, parallel=True, error_model="numpy")
def largest_rows(normal, position, mask, y0, x0, h, w, a, b, carry, c_n, cums, out):
    """Rows ``a``..``b`` - 1 of ``smooth_curvature``'s largest curvature (half-width 1) of
    ``_plane_of_units``' planes on the window (``h``, ``w``) from frame row ``y0`` and column
    ``x0``, into ``out`` (``b`` - ``a``, ``w``) float32: float32 on the pixels
    ``_curvature_unit`` finds on (0 elsewhere and where no valid pixel is near), with
    ``box_planes``' float64 sums (equal to the bit): along
    the columns, each box sum is the difference of the running sums of the window's planes from
    its first row, which ``carry`` (2, ``w``) float64 holds after its first ``c_n`` rows
    (``c_n`` <= max(``a`` - 1, 0); 0 and zeros to begin) and then holds after its first
    max(``b`` - 1, 0), the next rows' start. ``cums`` (2, at least min(``b`` + 1, ``h``) -
    max(``a`` - 1, 0) + 1, ``w``) float64: the running sums the rows read."""
    lo = max(a - 1, 0)
    hi = min(b + 1, h)
    keep = max(b - 1, 0)
    n_col = (w + SPREAD_STRIP - 1) // SPREAD_STRIP
    for item in prange(n_col):
        xa = item * SPREAD_STRIP
        xb = min(xa + SPREAD_STRIP, w)
        for j in range(xa, xb):
            if c_n >= lo:
                cums[0, c_n - lo, j] = carry[0, j]
                cums[1, c_n - lo, j] = carry[1, j]
        s0 = np.empty(SPREAD_STRIP, np.float64)
        s1 = np.empty(SPREAD_STRIP, np.float64)
        for j in range(xa, xb):
            s0[j - xa] = carry[0, j]
            s1[j - xa] = carry[1, j]
        # The unit normals of three rows (by row mod 3) of the strip's columns and one either side.
        ons = np.zeros((3, SPREAD_STRIP + 2), np.bool_)
        units = np.zeros((3, SPREAD_STRIP + 2, 3), np.float32)
        for n in range(max(c_n - 1, 0), min(c_n + 1, h)):
            _unit_row(normal, position, mask, y0, x0, w, n, xa, xb, ons, units)
        for n in range(c_n, hi):
            if n + 1 < h:
                _unit_row(normal, position, mask, y0, x0, w, n + 1, xa, xb, ons, units)
            for j in range(xa, xb):
                weight, value = _plane_of_units(position, y0, x0, h, w, np.int64(n), np.int64(j), xa, ons, units)
                s0[j - xa] = s0[j - xa] + weight
                s1[j - xa] = s1[j - xa] + value
                if n + 1 >= lo:
                    cums[0, n + 1 - lo, j] = s0[j - xa]
                    cums[1, n + 1 - lo, j] = s1[j - xa]
        for j in range(xa, xb):
            carry[0, j] = cums[0, keep - lo, j]
            carry[1, j] = cums[1, keep - lo, j]
    for row in prange(b - a):
        i = a + row
        top = max(i - 1, 0) - lo
        bottom = min(i + 2, h) - lo
        c0 = np.zeros(w + 1, np.float64)
        c1 = np.zeros(w + 1, np.float64)
        for j in range(w):
            c0[j + 1] = c0[j] + (cums[0, bottom, j] - cums[0, top, j])
            c1[j + 1] = c1[j] + (cums[1, bottom, j] - cums[1, top, j])
        for j in range(w):
            near = c0[min(j + 2, w)] - c0[max(j - 1, 0)]
            most = c1[min(j + 2, w)] - c1[max(j - 1, 0)]
            on, _, _, _ = _curvature_unit(normal, position, mask, y0 + i, x0 + j)
            out[row, j] = f32(most / max(near, 1.0)) if on and near > 0.0 else _ZERO


@njit(cache=True, parallel=True, error_model="numpy")
def composite(result, gain, albedo, diffuse, held, zeroed, mask, image, sss, overflow):
    """``core.pipeline.apply``'s compositing of one material, equal to the bit to its NumPy code: on each
    pixel of ``mask`` (H, W) the technique's ``result`` (H, W, 3) times ``gain`` (3,), and where
    all three are finite the SSS term, that minus ``albedo`` x ``diffuse`` where ``held`` (0 in
    the channels ``zeroed``), written into ``sss`` (H, W, 3) and added to ``image`` (H, W, C);
    ``overflow[y]`` counts row y's pixels of ``mask`` whose result is not finite. The same float32
    products, differences and sums as the NumPy code (no fused multiply-add)."""
    h, w = mask.shape
    for y in prange(h):
        bad = 0
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
                o0 = _ZERO
            if zeroed[1]:
                o1 = _ZERO
            if zeroed[2]:
                o2 = _ZERO
            sss[y, x, 0] = o0
            sss[y, x, 1] = o1
            sss[y, x, 2] = o2
            image[y, x, 0] = image[y, x, 0] + o0
            image[y, x, 1] = image[y, x, 1] + o1
            image[y, x, 2] = image[y, x, 2] + o2
        overflow[y] = bad


# --- auto's features (core/pipeline/auto.py) ---------------------------------------------------------------
# Not parallel: ``auto`` measures a material on at most 32 x 32 blocks, a few microseconds of work
# per call, less than a parallel launch costs. Each computes the NumPy code's operations in its
# order (``core.pipeline.auto``: ``_block_means``, ``_blurred``, the material's window in ``features``), so
# the features are the reference's to the bit; in check mode each call is compared with it.


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
        acc = _ZERO
        accd = 0.0
        for y in range(h):
            acc += e[y, x] if mask[y, x] else _ZERO
            accd += 1.0 if mask[y, x] else 0.0
            num[y + 1, x + 1] = acc
            den[y + 1, x + 1] = accd
    for y in range(1, h + 1):
        acc = _ZERO
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
