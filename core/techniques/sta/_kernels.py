"""Compiled (Numba) kernel of STA: one fused loop per pixel, parallel over groups of rows."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ...compute.jit import (
    EPS,
    ONE,
    QUARTER,
    R2_MIN,
    THREE,
    TINY,
    TWO,
    ZERO,
    add_kept_non_negative,
    bytes_span,
    clip,
    f32,
    fast_exp,
    normalize3,
    parallel_chunks,
    u64,
)
from ...optics._kernels import AREA, SPOT, SUN


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
    return vdot * (f32(-1.0) / (length if length > TINY else TINY)), length


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
    smooth = lights[k, 13] != ZERO
    for i in range(m):
        q = p3 + u64(3) * u64(i)  # unsigned: no wrap-around test, the loads stay vector loads
        lx, ly, lz, dist = normalize3(cx - pf[q], cy - pf[q + u64(1)], cz - pf[q + u64(2)])
        r2 = dist * dist
        r2 = r2 if r2 > R2_MIN else R2_MIN
        if kind == AREA:
            cos_l = lx * ax
            cos_l += ly * ay
            cos_l += lz * az
            cos_l = -cos_l
            cos_l = cos_l if cos_l > ZERO else ZERO
            e = e7 * cos_l / r2
        else:
            e = e7 / r2
            if kind == SPOT:
                ca = lx * ax
                ca += ly * ay
                ca += lz * az
                tc = -ca - half
                cone = ONE if tc > ZERO else ZERO
                if smooth:
                    u = clip((tc - ZERO) / width, ONE)
                    cone = cone * (u * u * (THREE - TWO * u))
                e = e * cone
        er[t, i] = e
        vd[t, i], lens[t, i] = _sta_half(
            lx, ly, lz, distortion, nxr[t, i], nyr[t, i], nzr[t, i], vxr[t, i], vyr[t, i], vzr[t, i]
        )


@njit(cache=True, error_model="numpy")
def _sta_lobe(power, m, t, vd, lens):
    """max(0, vd)^power in place (power 0: 1 where vd > 0), 0 where the direction vanished;
    the common powers without a call to pow, so that the loop vectorizes."""
    if power == ZERO:
        for i in range(m):
            vd[t, i] = ONE if vd[t, i] > ZERO and lens[t, i] > EPS else ZERO
    elif power == TWO:
        for i in range(m):
            v = vd[t, i] if vd[t, i] > ZERO else ZERO
            vd[t, i] = v * v if lens[t, i] > EPS else ZERO  # x^2 rounded once, as NumPy's square gives it
    elif power == ONE:
        for i in range(m):
            v = vd[t, i] if vd[t, i] > ZERO else ZERO
            vd[t, i] = v if lens[t, i] > EPS else ZERO
    else:
        for i in range(m):
            v = vd[t, i] if vd[t, i] > ZERO else ZERO
            vd[t, i] = v**power if lens[t, i] > EPS else ZERO


@njit(cache=True, error_model="numpy")
def _sta_spans(mask_flat, w, ya, yb, flat, spans):
    """The masked span of rows ``ya``..``yb`` into ``spans`` ((w, w) for a row without any),
    and the zeros of those rows off their span written as contiguous runs (a memset each);
    returns the widest span."""
    widest = 0
    for y in range(ya, yb):
        x0, x1 = bytes_span(mask_flat[y * w : (y + 1) * w])
        if x0 >= x1:
            x0 = w
            x1 = w
        spans[y, 0] = x0
        spans[y, 1] = x1
        widest = max(widest, x1 - x0)
        row = y * 3 * w
        flat[row : row + 3 * x0] = ZERO
        flat[row + 3 * x1 : row + 3 * w] = ZERO
    return widest


@njit(cache=True, error_model="numpy")
def _sta_kinds(lights):
    """(has a grey light, has a coloured one, the first grey light's row or -1) of the light
    table: flags set once before the parallel loop (Numba takes a variable assigned in several
    places of the loop's body for a possible alias, and then marks no argument as not aliasing)."""
    has_grey = False
    has_col = False
    for k in range(lights.shape[0]):
        if lights[k, 14] != ZERO:
            has_grey = True
        else:
            has_col = True
    first_grey_k = -1
    for k in range(lights.shape[0] - 1, -1, -1):
        if lights[k, 14] != ZERO:
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
        q = p3 + u64(3) * u64(i)
        a0 = af[q]
        s = a0 + af[q + u64(1)]
        s += af[q + u64(2)]
        nx = nf[q]
        ny = nf[q + u64(1)]
        nz = nf[q + u64(2)]
        px = pf[q]
        py = pf[q + u64(1)]
        pz = pf[q + u64(2)]
        th = tf[p1 + u64(i)]
        s += nx
        s += ny
        s += nz
        s += px
        s += py
        s += pz
        s += th
        okr[t, i] = ONE if (mf[p1 + u64(i)] != 0) & np.isfinite(s) else ZERO
        th = clip(th, ONE)
        tr[t, i] = ONE - th if flip else th
        nxr[t, i], nyr[t, i], nzr[t, i], _ = normalize3(nx, ny, nz)
        if ortho:
            vxr[t, i] = vx0
            vyr[t, i] = vy0
            vzr[t, i] = vz0
        else:
            vxr[t, i], vyr[t, i], vzr[t, i], _ = normalize3(vx0 - px, vy0 - py, vz0 - pz)


@njit(cache=True, inline="always", error_model="numpy")
def _sta_add(k, lights, m, t, scale, ambient, first_grey_k, vd, er, grey, c0, c1, c2):
    """Light ``k``'s term over the segment (its lobe in ``vd``, ``_sta_lobe``; a light other
    than a sun: its irradiance in ``er``) added to row ``t`` of the sums: a grey light's (times
    its colour's first channel if that is not 1) to ``grey`` (the first grey light sets it), a
    coloured one's times its colour to ``c0``, ``c1``, ``c2``."""
    sun = int(lights[k, 0]) == SUN
    is_grey = lights[k, 14] != ZERO
    first_grey = k == first_grey_k
    e_sun_pi = lights[k, 7] * f32(1.0 / math.pi)
    sun_scale = scale * e_sun_pi
    sun_ambient = ambient * e_sun_pi
    col0 = lights[k, 8]
    col1 = lights[k, 9]
    col2 = lights[k, 10]
    tint = is_grey & (col0 != ONE)
    for i in range(m):
        lobe = vd[t, i]
        if sun:
            lobe *= sun_scale
            if ambient != ZERO:
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
        xs = ONE - tr[t, i]
        sx = math.sqrt(math.sqrt(xs if xs > ZERO else ZERO)) * f32(nxs - 1)
        fl = np.floor(sx)
        fl = fl if fl < f32(nxs - 2) else f32(nxs - 2)
        tr[t, i] = sx - fl
        mu = nxr[t, i] * vxr[t, i]
        mu += nyr[t, i] * vyr[t, i]
        mu += nzr[t, i] * vzr[t, i]
        mu = abs(mu)
        sm = (mu if mu < ONE else ONE) * f32(nmu - 1)
        fm = np.floor(sm)
        fm = fm if fm < f32(nmu - 2) else f32(nmu - 2)
        vd[t, i] = sm - fm
        cell[t, i] = np.int32(3) * (np.int32(fl) * np.int32(nmu) + np.int32(fm))


@njit(cache=True, inline="always", error_model="numpy")
def _sta_medium_out(af, flat, p3, o3, m, t, has_col, wclip, ib0, ib1, ib2, okr, grey, c0, c1, c2, t0, t1, t2):
    """The medium's products of the segment into ``flat`` from its value ``o3`` on (the albedo's
    first value of the segment at ``p3``): the albedo times ``inv_base`` (``ib0``, ``ib1``,
    ``ib2``; clipped to [0, 1] with ``wclip``) times the light times the table's transmittance
    (``t0``, ``t1``, ``t2``), 0 where ``okr`` is 0."""
    for i in range(m):
        q = p3 + u64(3) * u64(i)
        r = o3 + u64(3) * u64(i)
        if has_col:
            l0 = c0[t, i]
            l1 = c1[t, i]
            l2 = c2[t, i]
        else:
            l0 = grey[t, i]
            l1 = l0
            l2 = l0
        w0 = af[q] * ib0
        w1 = af[q + u64(1)] * ib1
        w2 = af[q + u64(2)] * ib2
        if wclip:
            w0 = clip(w0, ONE)
            w1 = clip(w1, ONE)
            w2 = clip(w2, ONE)
        o = okr[t, i] != ZERO
        flat[r] = w0 * l0 * t0[t, i] if o else ZERO
        flat[r + u64(1)] = w1 * l1 * t1[t, i] if o else ZERO
        flat[r + u64(2)] = w2 * l2 * t2[t, i] if o else ZERO


@njit(cache=True, inline="always", error_model="numpy")
def _sta_out(af, flat, p3, o3, m, t, has_col, burley, distance, three_d, okr, tr, grey, c0, c1, c2):
    """The products of the segment into ``flat`` from its value ``o3`` on, without a medium (the
    albedo's first value of the segment at ``p3``): the albedo times the light times the
    translucency (``burley``: times the transmittance through ``distance`` sqrt(1 - t) for the
    profile lengths ``three_d``), 0 where ``okr`` is 0."""
    for i in range(m):
        q = p3 + u64(3) * u64(i)
        r = o3 + u64(3) * u64(i)
        th = tr[t, i]
        o = okr[t, i] != ZERO
        if burley:
            xs = ONE - th
            xs = distance * math.sqrt(xs if xs > ZERO else ZERO)
            for c in range(3):
                if has_col:
                    light = c0[t, i] if c == 0 else c1[t, i] if c == 1 else c2[t, i]
                else:
                    light = grey[t, i]
                if three_d[c] > ZERO:
                    e3 = fast_exp(-xs / three_d[c])
                    tm = QUARTER * (e3 * e3 * e3 + THREE * e3)
                else:
                    tm = ONE if xs == ZERO else ZERO
                v = af[q + u64(c)] * light * tm
                flat[r + u64(c)] = v if o else ZERO
        elif not has_col:
            g = grey[t, i] * th
            flat[r] = af[q] * g if o else ZERO
            flat[r + u64(1)] = af[q + u64(1)] * g if o else ZERO
            flat[r + u64(2)] = af[q + u64(2)] * g if o else ZERO
        else:
            flat[r] = af[q] * (c0[t, i] * th) if o else ZERO
            flat[r + u64(1)] = af[q + u64(1)] * (c1[t, i] * th) if o else ZERO
            flat[r + u64(2)] = af[q + u64(2)] * (c2[t, i] * th) if o else ZERO


#: Rows per work item of ``sta_kernel``.
STA_ROWS = 16


#: Pixels of a row that ``sta_kernel``'s loops take at a time: its row buffers (19 x 4 KB) stay
#: in the second-level cache whatever the frame's width (4K, one thread: 5 % faster than whole rows).
STA_SEGMENT = 1024


@njit(cache=True, inline="always", error_model="numpy")
def _sta_rows(n, w):
    return np.empty((n, w), np.float32)


@njit(cache=True, parallel=True, error_model="numpy")
@parallel_chunks(1)
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
                p1 = u64(y * w + x0)
                p3 = u64(3) * p1
                _sta_pixels(
                    af, nf, pf, tf, mf, p1, p3, m, t, flip, ortho, vx0, vy0, vz0, okr, tr, nxr, nyr, nzr, vxr, vyr, vzr
                )
                for i in range(m):
                    grey[t, i] = ZERO
                if has_col:
                    for i in range(m):
                        c0[t, i] = ZERO
                        c1[t, i] = ZERO
                        c2[t, i] = ZERO
                for k in range(n_lights):
                    _sta_light(k, lights, pf, p3, m, distortion, t, nxr, nyr, nzr, vxr, vyr, vzr, vd, lens, er)
                    _sta_lobe(power, m, t, vd, lens)
                    _sta_add(k, lights, m, t, scale, ambient, first_grey_k, vd, er, grey, c0, c1, c2)
                if sum_grey:  # the light per channel into c0, c1, c2
                    for i in range(m):
                        g = grey[t, i] if has_grey else ZERO
                        c0[t, i] += g
                        c1[t, i] += g
                        c2[t, i] += g
                if medium:
                    # The table's coordinates (a loop that vectorizes), its reads one pixel at a time
                    # (vector gathers were slower), then the products (which vectorize).
                    _sta_cells(m, t, nxs, nmu, tr, nxr, nyr, nzr, vxr, vyr, vzr, vd, cell)
                    _sta_table(tab, dtab, m, t, cell, tr, vd, t0, t1, t2)
                    _sta_medium_out(
                        af, flat, p3, p3, m, t, has_col, wclip, ib0, ib1, ib2, okr, grey, c0, c1, c2, t0, t1, t2
                    )
                else:
                    _sta_out(af, flat, p3, p3, m, t, has_col, burley, distance, three_d, okr, tr, grey, c0, c1, c2)


@njit(cache=True, error_model="numpy")
def _sta_table(tab, dtab, m, t, cell, fxr, fmr, t0, t1, t2):
    """The medium's table (flat, (x, mu, 3)) read bilinearly at each pixel of the row's span
    (the first of its four nodes at ``cell``, fractions ``fxr`` and ``fmr``; row ``t`` of each
    buffer) into ``t0``, ``t1``, ``t2``: ``core.techniques.sta.technique._lookup``'s operations in its order, with
    the differences along x read from ``dtab`` (``tab`` one x further minus ``tab``: the same
    float32 subtractions, made once per node instead of once per pixel)."""
    for i in range(m):
        c = u64(cell[t, i])
        fx = fxr[t, i]
        fm = fmr[t, i]
        lo0 = tab[c] + fx * dtab[c]
        lo1 = tab[c + u64(1)] + fx * dtab[c + u64(1)]
        lo2 = tab[c + u64(2)] + fx * dtab[c + u64(2)]
        hi0 = tab[c + u64(3)] + fx * dtab[c + u64(3)]
        hi1 = tab[c + u64(4)] + fx * dtab[c + u64(4)]
        hi2 = tab[c + u64(5)] + fx * dtab[c + u64(5)]
        t0[t, i] = lo0 + fm * (hi0 - lo0)
        t1[t, i] = lo1 + fm * (hi1 - lo1)
        t2[t, i] = lo2 + fm * (hi2 - lo2)


#: Values a pixel of Combined (RGBA, RGB), as the constants the route's loops are compiled with.
_FOUR = u64(4)
_THREE = u64(3)


@njit(cache=True, inline="always", error_model="numpy")
def _index_span(mi, p0, w, target):
    """(first, last + 1) of the pixels of the row whose flat Material Index values start at
    ``p0`` (``w`` of them) that round to ``target`` (``np.rint``: NaN and infinities to none);
    first >= last + 1 when there are none. 32 pixels at a time where none does (a loop that
    vectorizes), then one at a time."""
    x0 = 0
    while x0 + 32 <= w:
        acc = False
        for k in range(32):
            acc |= np.rint(mi[p0 + u64(x0 + k)]) == target
        if acc:
            break
        x0 += 32
    while x0 < w and np.rint(mi[p0 + u64(x0)]) != target:
        x0 += 1
    x1 = w
    while x1 - 32 >= x0:
        acc = False
        for k in range(32):
            acc |= np.rint(mi[p0 + u64(x1 - 32 + k)]) == target
        if acc:
            break
        x1 -= 32
    while x1 > x0 and np.rint(mi[p0 + u64(x1 - 1)]) != target:
        x1 -= 1
    return x0, x1


@njit(cache=True, inline="always", error_model="numpy")
def _route_select(af, nf, pf, tf, img, ic, keep, mi, target, p1, m, mf):
    """The pixels of a segment (``m`` pixels, the first at flat pixel ``p1``) that
    ``core.pipeline.apply`` runs a technique on: ``mf`` 1 where the Material Index rounds to
    ``target`` and every value of the pixel's inputs is finite (albedo, normal and position, the
    thickness ``tf``, and the RGB of Combined, whose copy ``img`` has ``ic`` values a pixel: a
    constant where it is called), else 0. Returns (pixels of the index, those of them not finite).

    The alpha of an RGBA Combined is read too, its finiteness or'ed with ``keep`` (always True,
    unknown to the compiler): a group of loads that skips a value of each pixel does not vectorize
    (3.9 against 0.6 ms on a million pixels, one thread)."""
    on_count = 0
    both_count = 0
    for i in range(m):
        p = p1 + u64(i)
        q = u64(3) * p
        c = ic * p
        fin = np.isfinite(af[q]) & np.isfinite(af[q + u64(1)]) & np.isfinite(af[q + u64(2)])
        fin &= np.isfinite(nf[q]) & np.isfinite(nf[q + u64(1)]) & np.isfinite(nf[q + u64(2)])
        fin &= np.isfinite(pf[q]) & np.isfinite(pf[q + u64(1)]) & np.isfinite(pf[q + u64(2)])
        fin &= np.isfinite(img[c]) & np.isfinite(img[c + u64(1)]) & np.isfinite(img[c + u64(2)])
        if ic == _FOUR:
            fin &= np.isfinite(img[c + u64(3)]) | keep
        fin &= np.isfinite(tf[p])
        on = np.rint(mi[p]) == target
        both = on & fin
        mf[p] = np.uint8(both)
        on_count += np.int32(on)
        both_count += np.int32(both)
    return on_count, on_count - both_count


@njit(cache=True, inline="always", error_model="numpy")
def _route_gain(res, o3, m, g0, g1, g2, weighted, weight):
    """The technique's result of the segment (from value ``o3`` of ``res`` on) times the gain per
    channel and, with ``weighted``, times the Subsurface Weight ``weight``, in place: the float32
    products ``core.pipeline.apply`` makes (``_weighted``, then ``_composite``, which multiplies by
    1 there); returns whether all of them are finite."""
    ok = True
    for i in range(m):
        r = o3 + u64(3) * u64(i)
        v0 = res[r] * g0
        v1 = res[r + u64(1)] * g1
        v2 = res[r + u64(2)] * g2
        if weighted:
            v0 = v0 * weight
            v1 = v1 * weight
            v2 = v2 * weight
        res[r] = v0
        res[r + u64(1)] = v1
        res[r + u64(2)] = v2
        ok &= np.isfinite(v0) & np.isfinite(v1) & np.isfinite(v2)
    return ok


@njit(cache=True, inline="always", error_model="numpy")
def _put_term(img, c, sf, s, o0, o1, o2):
    """One pixel of the compositing: Combined (``img`` from ``c`` on) plus the term (``o0``, ``o1``,
    ``o2``) into ``img``, the term as kept into ``sf`` from ``s`` on, each channel clamped as
    ``core.compute.jit.add_kept_non_negative`` clamps it. Returns whether a channel was clamped."""
    o0, t0, n0 = add_kept_non_negative(img[c], o0)
    o1, t1, n1 = add_kept_non_negative(img[c + u64(1)], o1)
    o2, t2, n2 = add_kept_non_negative(img[c + u64(2)], o2)
    sf[s] = o0
    sf[s + u64(1)] = o1
    sf[s + u64(2)] = o2
    img[c] = t0
    img[c + u64(1)] = t1
    img[c + u64(2)] = t2
    return n0 | n1 | n2


@njit(cache=True, inline="always", error_model="numpy")
def _route_put(res, o3, p1, m, img, ic, keep, sf):
    """``core.pipeline._kernels.composite`` on a segment whose every pixel is composited and
    finite: Combined (``img``, ``ic`` values a pixel, a constant where it is called) plus the term
    (``res`` from ``o3`` on) into ``img`` and the term into ``sf``, a channel that would turn a
    non-negative Combined negative set to 0 (its term to minus Combined). Selects, no branches,
    so that the loop vectorizes; an RGBA pixel's alpha is written back as it was (``keep`` always
    True, unknown to the compiler, which would drop the store): a group of stores that skips a
    value of each pixel does not vectorize (6.1 against 1.4 ms on a million pixels, one thread).
    Returns the pixels clamped."""
    clamped = 0
    for i in range(m):
        r = o3 + u64(3) * u64(i)
        p = p1 + u64(i)
        s = u64(3) * p
        c = ic * p
        o0 = res[r]
        o1 = res[r + u64(1)]
        o2 = res[r + u64(2)]
        hit = _put_term(img, c, sf, s, o0, o1, o2)
        if ic == _FOUR:
            alpha = img[c + u64(3)]
            img[c + u64(3)] = alpha if keep else ZERO
        clamped += np.int32(hit)
    return clamped


@njit(cache=True, inline="always", error_model="numpy")
def _route_put_some(res, o3, p1, m, mf, img, ic, sf):
    """``_route_put`` on a segment of which some pixels are left as they are (``mf`` 0) or have a
    result that is not finite (left as they were, counted): one pixel at a time, with branches,
    as ``core.pipeline._kernels.composite``. Returns (pixels not finite, pixels clamped)."""
    bad = 0
    clamped = 0
    for i in range(m):
        p = p1 + u64(i)
        if mf[p] == 0:
            continue
        r = o3 + u64(3) * u64(i)
        o0 = res[r]
        o1 = res[r + u64(1)]
        o2 = res[r + u64(2)]
        if not (np.isfinite(o0) and np.isfinite(o1) and np.isfinite(o2)):
            bad += 1
            continue
        s = u64(3) * p
        c = ic * p
        clamped += _put_term(img, c, sf, s, o0, o1, o2)
    return bad, clamped


@njit(cache=True, parallel=True, error_model="numpy")
@parallel_chunks(1)
def sta_composite(
    albedo,
    normal,
    position,
    thickness,
    index,
    target,
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
    gains,
    weighted,
    weight,
    image,
    ic,
    sss,
    w,
    selected,
    keep,
    counts,
):
    """STA on the pixels of one material composited into the layers, in one pass: what
    ``core.pipeline.apply`` does with ``sta_kernel``'s result and ``core.pipeline._kernels.composite``,
    to the bit, on the passes as they are (flat float32 arrays, rows of ``w`` pixels).

    The material's pixels are those whose Material Index (``index``) rounds to ``target``, and of
    them apply's pixels those whose every input value is finite (``albedo``, ``normal``,
    ``position`` three a pixel, ``thickness`` one, and the RGB of Combined in its copy ``image``,
    ``ic`` values a pixel, 3 or 4): ``selected`` (one byte a pixel, a scratch frame of which only
    the rows' spans are written) marks them. On those, ``sta_kernel``'s arithmetic (its other
    arguments are ``sta_kernel``'s; ``lights`` without any row: its result is 0), times ``gains``
    (3,) and, with ``weighted``, the Subsurface Weight ``weight``; where the three are finite the
    term goes into ``sss`` (three a pixel) and Combined plus the term into ``image``, a channel
    that would turn a non-negative Combined negative set to 0 (its term to minus Combined).
    ``keep``: True (``_route_select``, ``_route_put``). ``counts[y]``: row y's pixels of the
    material with an input that is not finite, with a result that is not finite, and clamped.

    Work items of ``STA_ROWS`` rows; per row the span of the material's pixels, ``STA_SEGMENT``
    pixels at a time: the selection (``_route_select``), ``sta_kernel``'s loops into a row buffer,
    then the compositing, split by case (``_route_gain``, then ``_route_put`` where every pixel of
    the segment is composited and finite, a loop without branches that vectorizes, else
    ``_route_put_some``, one pixel at a time): conditions inside one loop would become masked loads
    and stores."""
    h = counts.shape[0]
    n_lights = lights.shape[0]
    has_grey, has_col, first_grey_k = _sta_kinds(lights)
    sum_grey = has_col and (has_grey or medium or burley)
    tab = table.reshape(-1)
    dtab = _sta_steps(tab, 3 * table.shape[1])
    n_items = (h + STA_ROWS - 1) // STA_ROWS
    seg = min(w, STA_SEGMENT)
    nxr, nyr, nzr = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    vxr, vyr, vzr = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    tr, okr, grey = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    c0, c1, c2 = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    vd, lens, er = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    t0, t1, t2 = _sta_rows(n_items, seg), _sta_rows(n_items, seg), _sta_rows(n_items, seg)
    cell = np.empty((n_items, seg), np.int32)
    res = np.empty(n_items * 3 * seg, np.float32)
    vx0 = view[0]
    vy0 = view[1]
    vz0 = view[2]
    ib0 = inv_base[0]
    ib1 = inv_base[1]
    ib2 = inv_base[2]
    g0 = gains[0]
    g1 = gains[1]
    g2 = gains[2]
    nxs = table.shape[0]
    nmu = table.shape[1]
    for item in prange(n_items):
        t = item  # its row of each buffer
        o3 = u64(3 * seg) * u64(t)  # its part of ``res``
        ya = item * STA_ROWS
        yb = min(ya + STA_ROWS, h)
        for y in range(ya, yb):
            counts[y, 0] = 0
            counts[y, 1] = 0
            counts[y, 2] = 0
            xa, xe = _index_span(index, u64(y * w), w, target)
            for x0 in range(xa, xe, STA_SEGMENT):
                m = min(STA_SEGMENT, xe - x0)
                # Flat indices, unsigned: no wrap-around tests, so the loops keep vector loads.
                p1 = u64(y * w + x0)
                p3 = u64(3) * p1
                # Combined's channels as a constant in each branch: loops with a stride known to LLVM.
                if ic == _FOUR:
                    on, bad = _route_select(
                        albedo, normal, position, thickness, image, _FOUR, keep, index, target, p1, m, selected
                    )
                else:
                    on, bad = _route_select(
                        albedo, normal, position, thickness, image, _THREE, keep, index, target, p1, m, selected
                    )
                counts[y, 0] += bad
                if on == bad:
                    continue
                if n_lights == 0:
                    for i in range(3 * m):
                        res[o3 + u64(i)] = ZERO
                else:
                    _sta_pixels(
                        albedo, normal, position, thickness, selected, p1, p3, m, t, flip, ortho, vx0, vy0, vz0,
                        okr, tr, nxr, nyr, nzr, vxr, vyr, vzr,
                    )  # fmt: skip
                    for i in range(m):
                        grey[t, i] = ZERO
                    if has_col:
                        for i in range(m):
                            c0[t, i] = ZERO
                            c1[t, i] = ZERO
                            c2[t, i] = ZERO
                    for k in range(n_lights):
                        _sta_light(
                            k, lights, position, p3, m, distortion, t, nxr, nyr, nzr, vxr, vyr, vzr, vd, lens, er
                        )
                        _sta_lobe(power, m, t, vd, lens)
                        _sta_add(k, lights, m, t, scale, ambient, first_grey_k, vd, er, grey, c0, c1, c2)
                    if sum_grey:
                        for i in range(m):
                            gr = grey[t, i] if has_grey else ZERO
                            c0[t, i] += gr
                            c1[t, i] += gr
                            c2[t, i] += gr
                    if medium:
                        _sta_cells(m, t, nxs, nmu, tr, nxr, nyr, nzr, vxr, vyr, vzr, vd, cell)
                        _sta_table(tab, dtab, m, t, cell, tr, vd, t0, t1, t2)
                        _sta_medium_out(
                            albedo, res, p3, o3, m, t, has_col, wclip, ib0, ib1, ib2, okr, grey, c0, c1, c2, t0, t1, t2
                        )
                    else:
                        _sta_out(
                            albedo, res, p3, o3, m, t, has_col, burley, distance, three_d, okr, tr, grey, c0, c1, c2
                        )
                finite = _route_gain(res, o3, m, g0, g1, g2, weighted, weight)
                if finite and on - bad == m:
                    if ic == _FOUR:
                        counts[y, 2] += _route_put(res, o3, p1, m, image, _FOUR, keep, sss)
                    else:
                        counts[y, 2] += _route_put(res, o3, p1, m, image, _THREE, keep, sss)
                else:
                    over, clamped = _route_put_some(res, o3, p1, m, selected, image, ic, sss)
                    counts[y, 1] += over
                    counts[y, 2] += clamped
