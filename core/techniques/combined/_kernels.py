"""Compiled (Numba) kernels of the combined technique's light from behind: where it enters, how
much crosses the medium (``transmit_pixels``), and how it is finished into the frame."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ...compute.jit import ONE, ZERO, f32, nan_to_num32, nan_to_num64, norm3, normalize3
from ...optics._kernels import lamp_at


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
    t = t if np.isfinite(t) else ZERO
    return ONE - t if as_thickness else t


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
def _view_vector(px, py, pz, cam):
    """``core.scene.scene.Camera.view_vectors`` at one position (float32): ``cam`` = (1 for
    orthographic else 0, then the camera's position as float32, then -forward as float32)."""
    if cam[0] != ZERO:
        return cam[4], cam[5], cam[6]
    vx = cam[1] - px
    vy = cam[2] - py
    vz = cam[3] - pz
    n = norm3(vx, vy, vz)
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
            e[i, j, 0] = ZERO
            e[i, j, 1] = ZERO
            e[i, j, 2] = ZERO
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
                k = max(nan_to_num64(np.float64(largest[cy, cx])), 0.0)
                xs = _far_x(_translucency(thickness, y, x, as_thickness), distance, True, k, kmin)
                if walks:
                    s = min(max(xs * k / 2.0, 0.0), 1.0)
                    length = norm3(nx, ny, nz)
                    length = length if length > f32(1e-20) or length != length else f32(1e-20)
                    ux = nan_to_num32(nx / length)
                    uy = nan_to_num32(ny / length)
                    uz = nan_to_num32(nz / length)
                    vx, vy, vz = _view_vector(px, py, pz, cam)
                    nx = f32((1.0 - s) * np.float64(ux) + s * np.float64(vx))
                    ny = f32((1.0 - s) * np.float64(uy) + s * np.float64(vy))
                    nz = f32((1.0 - s) * np.float64(uz) + s * np.float64(vz))
                    if not (np.isfinite(nx) and np.isfinite(ny) and np.isfinite(nz)):
                        continue
            nx, ny, nz, _ = normalize3(nx, ny, nz)
            a0 = ZERO
            a1 = ZERO
            a2 = ZERO
            for q in range(n_lights):
                lx, ly, lz, el = lamp_at(lights, q, px, py, pz)
                back = -(nx * lx + ny * ly + nz * lz)
                back = back if back > ZERO or back != back else ZERO
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
                any_lit |= most > ZERO
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
        k = max(nan_to_num64(np.float64(largest[cy, cx])), 0.0)
    return _far_x(_translucency(thickness, y, x, as_thickness), distance, curved, k, kmin), k


@njit(cache=True, inline="always", error_model="numpy")
def _view_cos(normal, position, y, x, cam):
    """``core.techniques.combined.technique.view_cosine`` of one pixel: |nan_to_num(N / |N| . V)|, float32."""
    nx = normal[y, x, 0]
    ny = normal[y, x, 1]
    nz = normal[y, x, 2]
    length = norm3(nx, ny, nz)
    length = length if length > f32(1e-20) or length != length else f32(1e-20)
    vx, vy, vz = _view_vector(position[y, x, 0], position[y, x, 1], position[y, x, 2], cam)
    return abs(nan_to_num32(nx / length * vx + ny / length * vy + nz / length * vz))


_ROOT2 = math.sqrt(2.0)


@njit(cache=True, inline="always", error_model="numpy")
def _spread_width(kind, xs, spread_len, spread_counts, spread_nodes, spread_values, c):
    """``core.techniques.combined.technique.spread_sigma`` of channel ``c`` through thickness ``xs``, float32 (NaN where
    the walk's table ends; 0 for a length of 0)."""
    d = spread_len[c]
    n = spread_counts[c]
    if d <= 0.0 or n == 0:
        return ZERO
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
        return focal if np.isfinite(z) else ZERO
    scale = focal / z
    return scale if np.isfinite(scale) and not z <= ZERO else ZERO


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
            lit = finite and most > ZERO
            in_mask = spread and finite and mask[y, x]
            if not lit:
                light[i, j, 0] = ZERO
                light[i, j, 1] = ZERO
                light[i, j, 2] = ZERO
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
    if base > ZERO:
        a = a / (base if base > f32(1e-6) else f32(1e-6))
    else:
        a = ZERO
    a = a if a > ZERO or a != a else ZERO
    return a if a < ONE or a != a else ONE


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
        v = _finished(ZERO, albedo, y, x, c, pre_post, walks, base, True, scale, scaled)
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
