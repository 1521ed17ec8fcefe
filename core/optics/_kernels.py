"""Compiled (Numba) kernels of the shared physics: the gathers' common start (``prepare_pixels``),
the surface a pixel covers, the energy model's tables and curvature, the lights' table."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..compute.jit import BACKGROUND, EPS, INF, ONE, R2_MIN, THREE, TWO, ZERO, f32, normalize3, parallel_chunks

# Light types as numbers for the STA kernel (core.scene.scene.Light.type).
SUN, POINT, SPOT, AREA = 0, 1, 2, 3


#: Columns of the packed light table: type, position or direction (3), spot/area axis (3),
#: irradiance factor, colour (3), cos(half cone), smoothstep width, has a smooth edge, grey.
LIGHT_COLUMNS = 15


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
    inf_gate = gate == INF
    for y in prange(h):
        lo = w
        hi = -1
        least = INF
        most = ZERO
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
                s = focal if np.isfinite(z) else ZERO
            else:
                s = focal / z
                s = s if np.isfinite(s) and z > ZERO else ZERO
            take = mask[y, x] and z > ZERO and z < BACKGROUND
            take = take and np.isfinite(e0) and np.isfinite(e1) and np.isfinite(e2)
            take = take and np.isfinite(a0) and np.isfinite(a1) and np.isfinite(a2)
            take = take and (s > ZERO if inf_gate else gate * s > threshold)
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
            area[y, x] = area_at(depth, ok, far, ortho, f, cx, cy, min_cos, y, x)


@njit(cache=True, inline="always", error_model="numpy")
def _cos_at(depth, ok, far, ortho, f, cx, cy, oy, ox, y, x):
    """``core.optics.energy.view_cosine`` at pixel (``y``, ``x``) of a window whose first pixel is the
    frame's (``oy``, ``ox``): float64 operations in the reference's order (on each axis the
    difference to a neighbour of ``ok`` in the window with the smaller depth step, the next one
    on a tie; the normal their cross product), the clipped cosine rounded to float32; 1 where the
    pixel or a whole axis has no valid pixel (``ok`` with a depth in (0, ``far``))."""
    if not ok[y, x] or not 0.0 < depth[y, x] < far:
        return ONE
    px, py, pz = _camera_point(np.float64(y + oy), np.float64(x + ox), np.float64(depth[y, x]), ortho, f, cx, cy)
    ax, ay, az, found_x = _axis_step(depth, ok, far, y, x, 0, 1, px, py, pz, ortho, f, cx, cy, oy, ox)
    bx, by, bz, found_y = _axis_step(depth, ok, far, y, x, 1, 0, px, py, pz, ortho, f, cx, cy, oy, ox)
    if not (found_x and found_y):
        return ONE
    nx = ay * bz - az * by
    ny = az * bx - ax * bz
    nz = ax * by - ay * bx
    vx, vy, vz = (0.0, 0.0, 1.0) if ortho else (-px, -py, -pz)
    den = math.sqrt(nx * nx + ny * ny + nz * nz) * math.sqrt(vx * vx + vy * vy + vz * vz)
    c = abs(nx * vx + ny * vy + nz * vz) / den if den > 0.0 else np.nan
    if c != c:
        return ONE
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
            out[y, x] = ONE
            known[y, x] = False
            if not ok[y, x]:
                continue
            a = normal[y, x, 0]
            b = normal[y, x, 1]
            c = normal[y, x, 2]
            if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
                continue
            top = max(abs(a), abs(b), abs(c))
            if top == ZERO:
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
                dot = (n0 * rx + n1 * ry + n2) / f32(math.sqrt(rx * rx + ry * ry + ONE))
            cos = abs(dot) / length
            if not (math.isfinite(cos) and length > f32(1e-6)):
                continue
            known[y, x] = True
            out[y, x] = min(cos, ONE)


@njit(cache=True, inline="always", error_model="numpy")
def area_at(depth, ok, far, ortho, f, cx, cy, min_cos, y, x):
    """``surface_area``'s value at pixel (``y``, ``x``): 1 where the view cosine is 1, which
    ``_cos_at`` also gives a pixel off ``ok`` or without a valid depth."""
    # The reference rounds the view cosine to float32 before the ratio.
    cos = np.float64(_cos_at(depth, ok, far, ortho, f, cx, cy, 0, 0, y, x))
    if cos >= 1.0:
        return ONE
    axis = 1.0
    if not ortho:
        u = (x + 0.5 - cx) / f
        v = (cy - y - 0.5) / f
        axis = 1.0 / math.sqrt(1.0 + u * u + v * v)
    return f32(min(axis / max(cos, 1e-30), 1.0 / min_cos))


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
@parallel_chunks(1 << 14)
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
            shell = ONE
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
                gain = _bilinear(entry, iv, fv, ia, fa) if entry.shape[0] > 0 else ONE
                cv = ONE
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
                    cv = ONE + (cv - ONE) * shell
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
        return False, ZERO, ZERO, ZERO
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
                if on[y, x] and (ok_n or ok_p) and dd > ZERO:
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
def smooth_curvature(mean, most, valid, on, radii, largest, out_mean, out_most):
    """``core.optics.energy._smoothed_curvatures``: ``mean`` (float64) averaged over the pixels of
    ``valid`` within the square of half-width ``radii[k]``, float32 into ``out_mean[k]``, for each
    k, and with ``largest`` ``most`` averaged so at the last (widest) radius into ``out_most``;
    on ``on`` (0 elsewhere and where no pixel of ``valid`` is near).

    The box sums are the reference's (``core.optics.energy._box_sum``), equal to the bit: its
    float64 running sums along a column, from 0, are the same whatever the radius, so they are
    taken once for all radii (a frame per plane: the weight, and ``mean`` and ``most`` times it);
    a column's box sum at row i is the running sum at row min(i + r, H - 1) less the one at row
    i - r - 1 (nothing above the first row), as the reference's differences of its cumulative
    sums of the padded column give it. Then per row and radius the running sums along the row of
    those box sums, and their differences, as the reference's, and the division."""
    h, w = valid.shape
    n = 3 if largest else 2
    planes = np.empty((n, h, w), np.float64)
    n_col = (w + SPREAD_STRIP - 1) // SPREAD_STRIP
    for item in prange(n_col):
        x0 = item * SPREAD_STRIP
        x1 = min(x0 + SPREAD_STRIP, w)
        run = np.zeros((3, SPREAD_STRIP), np.float64)
        for y in range(h):
            for x in range(x0, x1):
                t = x - x0
                weight = 1.0 if valid[y, x] else 0.0
                run[0, t] = run[0, t] + weight
                planes[0, y, x] = run[0, t]
                run[1, t] = run[1, t] + mean[y, x] * weight
                planes[1, y, x] = run[1, t]
                if largest:
                    run[2, t] = run[2, t] + most[y, x] * weight
                    planes[2, y, x] = run[2, t]
    widest = radii.size - 1
    for y in prange(h):
        column = np.empty((3, w), np.float64)
        for k in range(radii.size):
            r = radii[k]
            below = min(y + r, h - 1)
            above = y - r - 1
            m = 3 if largest and k == widest else 2
            cum = np.zeros((m, w + 2 * r + 1), np.float64)
            for p in range(m):
                for x in range(w):
                    column[p, x] = planes[p, below, x] - (planes[p, above, x] if above >= 0 else 0.0)
                for x in range(w):
                    cum[p, r + 1 + x] = cum[p, r + x] + column[p, x]
                for x in range(r):
                    cum[p, r + 1 + w + x] = cum[p, r + w + x]
            for x in range(w):
                near = cum[0, 2 * r + 1 + x] - cum[0, x]
                keep = on[y, x] and near > 0.0
                den = max(near, 1.0)
                out_mean[k, y, x] = f32((cum[1, 2 * r + 1 + x] - cum[1, x]) / den) if keep else ZERO
                if m == 3:
                    out_most[y, x] = f32((cum[2, 2 * r + 1 + x] - cum[2, x]) / den) if keep else ZERO


#: Columns (vertical passes) or rows (horizontal ones) per work item of ``spread_light``'s box sums.
SPREAD_STRIP = 16


@njit(cache=True, inline="always", error_model="numpy")
def lamp_at(lights, k, px, py, pz):
    """(lx, ly, lz, E_L) of light ``k`` of ``light_table``'s ``lights`` at the float32 point
    (px, py, pz): ``core.optics.lights.light_at``'s float32 operations in its order, NaN carried through its
    maxima and clip as NumPy's do (a sun's direction and irradiance are its table's)."""
    kind = int(lights[k, 0])
    if kind == SUN:
        return lights[k, 1], lights[k, 2], lights[k, 3], lights[k, 7]
    lx, ly, lz, dist = normalize3(lights[k, 1] - px, lights[k, 2] - py, lights[k, 3] - pz)
    r2 = dist * dist
    r2 = r2 if r2 > R2_MIN or r2 != r2 else R2_MIN
    if kind == AREA:
        cos_l = -(lx * lights[k, 4] + ly * lights[k, 5] + lz * lights[k, 6])
        cos_l = cos_l if cos_l > ZERO or cos_l != cos_l else ZERO
        return lx, ly, lz, lights[k, 7] * cos_l / r2
    e = lights[k, 7] / r2
    if kind == SPOT:
        tc = -(lx * lights[k, 4] + ly * lights[k, 5] + lz * lights[k, 6]) - lights[k, 11]
        cone = ONE if tc > ZERO else ZERO
        if lights[k, 13] != ZERO:
            u = tc / lights[k, 12]
            u = u if u > ZERO or u != u else ZERO
            u = u if u < ONE or u != u else ONE
            cone = cone * (u * u * (THREE - TWO * u))
        e = e * cone
    return lx, ly, lz, e


@njit(cache=True, inline="always", error_model="numpy")
def _lamp_cosine(lights, k, nx, ny, nz, px, py, pz):
    """max(0, N . L) E_L / pi of light ``k`` at the float32 point (px, py, pz) for the float64
    normal (nx, ny, nz), in float64: ``core.optics.energy.mean_lamp_irradiance``'s per-row term."""
    lx, ly, lz, e = lamp_at(lights, k, px, py, pz)
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
                    e = e / (EPS if a < EPS else a)
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
    mean curvature: (1 where valid else 0, the largest times that: the planes ``smooth_curvature`` sums).
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
        b0 = b1 = b2 = ZERO
        if ib < h and jb < w:
            sb, kb = ib % 3, k + dj
            ok_n, b0, b1, b2 = ons[sb, kb], units[sb, kb, 0], units[sb, kb, 1], units[sb, kb, 2]
        ok_p = False
        a0 = a1 = a2 = ZERO
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
        if on and (ok_n or ok_p) and dd > ZERO:
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
    ``smooth_curvature``'s float64 sums (equal to the bit): along
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
            out[row, j] = f32(most / max(near, 1.0)) if on and near > 0.0 else ZERO
