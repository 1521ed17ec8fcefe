"""Compiled (Numba) kernels of Burley's gather: the packed frame, the spiral's angles, the gather
over tiles and its clean-up."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ...compute.jit import INF, TINY, ZERO, clip, f32, fast_exp, parallel_chunks, scale_of, u64
from ...optics._kernels import area_at


@njit(cache=True, error_model="numpy")
def _burley_positions(xf, yf, s, rc, rsn, tables, g, nk, wl, hl, py0, px0, ph, pw, js, inside):
    """Where the ``nk`` spiral samples (``tables[:, g]``) of the pixel (``xf``, ``yf``) land, as
    the reference computes it: sample k reads the pixel js[k] of the packed pixels (``burley_pack``, flat: ``ph`` rows
    from ``py0`` of ``pw`` columns from ``px0``), which the reference keeps only if ``inside[k]``
    (the rounded position is on the image). Compiled without fastmath and called from the
    kernels, never from a function with fastmath (Numba compiles a function's callees with its
    flags): the pixels read are the reference's to the bit. The loop vectorizes (no gathers).
    The packed pixels reach beyond every sample (``core.techniques.burley.technique._compiled``); the row and the
    column are clamped to them all the same, so that nothing outside them is ever read."""
    for k in range(nk):
        ca = rc * tables[2, g, k] - rsn * tables[3, g, k]
        sa = rsn * tables[2, g, k] + rc * tables[3, g, k]
        rad = s * tables[0, g, k]
        xs = rad * ca
        xs += xf
        xs = np.rint(xs)
        ys = rad * sa
        ys += yf
        ys = np.rint(ys)
        xc = clip(xs, wl)
        yc = clip(ys, hl)
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
def _burley_pixel(packed, area, ids, id_base, q, tables, g, nk, js, inside, k0, k1, k2, sums):
    """The ``nk`` spiral samples of pixel ``q``, read where ``_burley_positions`` put them, summed
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
    n0 = ZERO
    n1 = ZERO
    n2 = ZERO
    d0 = ZERO
    d1 = ZERO
    d2 = ZERO
    for k in range(nk):
        j4 = np.int32(js[k] * np.int32(4))
        zj = packed[np.int32(j4 + np.int32(3))]
        aj = area[js[k]]
        valid = inside[k] & (zj < INF)
        if use_ids:
            valid &= ids[js[k] + id_base] == own
        # The depth of what the sample lands on: its key where it takes part, else -area.
        zo = zj if zj < INF else -aj
        hidden = inside[k] & (not valid) & (zo < zc)
        rp = (zc if hidden else zj) - zc
        rp *= rp
        rp += tables[1, g, k]
        rp = math.sqrt(rp)
        ratio = tables[4, g, k] / (rp if rp > TINY else TINY)
        ratio *= ac if hidden else aj
        e3 = fast_exp(rp * k0)
        w0 = (e3 * e3 * e3 + e3) * ratio
        e3 = fast_exp(rp * k1)
        w1 = (e3 * e3 * e3 + e3) * ratio
        e3 = fast_exp(rp * k2)
        w2 = (e3 * e3 * e3 + e3) * ratio
        use = valid | hidden
        d0 += w0 if use else ZERO
        d1 += w1 if use else ZERO
        d2 += w2 if use else ZERO
        n0 += w0 * (c0 if hidden else packed[j4]) if use else ZERO
        n1 += w1 * (c1 if hidden else packed[np.int32(j4 + np.int32(1))]) if use else ZERO
        n2 += w2 * (c2 if hidden else packed[np.int32(j4 + np.int32(2))]) if use else ZERO
    sums[0] = n0
    sums[1] = n1
    sums[2] = n2
    sums[3] = d0
    sums[4] = d1
    sums[5] = d2


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
            packed[i, j, 0] = light[y, x, 0] if o else ZERO
            packed[i, j, 1] = light[y, x, 1] if o else ZERO
            packed[i, j, 2] = light[y, x, 2] if o else ZERO
            packed[i, j, 3] = depth[y, x] if o else INF
            if o:
                packed_area[i, j] = area_at(depth, ok, far, ortho, f, cx, cy, min_cos, y, x)
            else:
                packed_area[i, j] = -depth[y, x] if depth[y, x] > ZERO else -INF


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
            phi[i, j] = f32(v >> np.uint64(40)) * to_angle if ok[y, x] else ZERO


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
    light, packed, packed_area, py0, px0, ok, cam, ids, group, tables, counts, limit, blocks, block, fp_reach,
    rot_cos, rot_sin, rot_y0, rot_x0, inv3d, reach, ya, yb, xa, xb, buf,
):  # fmt: skip
    """core.techniques.burley.technique's gather (the scattered light, before the albedo) of the pixels ``ok`` of
    rows ``ya``..``yb`` - 1 and columns ``xa``..``xb`` - 1 into ``buf`` (3, from (ya, xa)),
    reading the samples from ``packed`` (``burley_pack``, rows from ``py0``, columns from ``px0``);
    ``rot_cos``/``rot_sin`` hold rows from ``rot_y0`` and columns from ``rot_x0``. Each pixel
    takes the samples of its level (``core.techniques.burley.adaptive.Plan.levels``): the first
    with ``limit`` >= its footprint (float64 scale x ``fp_reach`` of its group), at most its
    block's (``blocks``, blocks of ``block`` pixels); its spiral is row level x groups + group of
    ``tables``, its first ``counts[level]`` entries."""
    h, w = ok.shape
    rotate = rot_cos.size > 1
    grouped = group.size > 1
    n_groups = tables.shape[1] // counts.size
    top = counts.size - 1
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
                s = scale_of(flat[np.int32(np.int32(4) * np.int32((y - py0) * pw + x - px0) + np.int32(3))], cam)
                rc = rot_cos[y - rot_y0, x - rot_x0] if rotate else rot_cos[0, 0]
                rsn = rot_sin[y - rot_y0, x - rot_x0] if rotate else rot_sin[0, 0]
                g = group[y, x] if grouped else 0
                footprint = np.float64(s) * fp_reach[g]
                footprint *= footprint
                level = 0
                while level < top and limit[level] < footprint:
                    level += 1
                level = min(level, blocks[y // block, x // block])
                row = level * n_groups + g
                nk = counts[level]
                _burley_positions(f32(x), f32(y), s, rc, rsn, tables, row, nk, wl, hl, py0, px0, ph, pw, js, inside)
                q = (y - py0) * pw + x - px0
                _burley_pixel(flat, area, ids, py0 * w, q, tables, row, nk, js, inside, k0, k1, k2, sums)
                for c in range(3):
                    den = sums[3 + c]
                    if reach[c] <= 0.0 or reach[c] * np.float64(s) <= 1.0 or den <= TINY:
                        v = light[y, x, c]
                    else:
                        v = sums[c] / den
                    buf[c, y - ya, x - xa] = v


@njit(cache=True, parallel=True, error_model="numpy")
@parallel_chunks(1)
def burley_kernel(
    light, packed, packed_area, py0, px0, ok, cam, ids, group, tables, counts, limit, blocks, block, fp_reach,
    rot_cos, rot_sin, rot_y0, rot_x0, inv3d, reach, extents, depth, tol, radius, min_px, post, y_lo, y_hi, x_lo, x_hi,
    out,
):  # fmt: skip
    """core.techniques.burley.technique's gather and clean-up (``_smooth``, when ``radius`` > 0) over the pixels
    ``ok`` of rows ``y_lo``..``y_hi`` - 1 and columns ``x_lo``..``x_hi`` - 1 (which hold all
    those of these rows), times ``post``, into ``out``.

    ``packed`` (``burley_pack``) rows from ``py0`` and columns from ``px0`` (every pixel a sample
    of these pixels reaches; whole rows when there are ids), with ``packed_area`` the surface
    each of them covers over a pixel facing the camera (``core.optics.surface.surface_area``), a factor
    of its samples' weights:
    per pixel (R, G, B, depth) where ``ok``, (0, 0, 0, +inf) elsewhere; ``tables``
    (5, L x G, n): per count of the plan and object group (row level x G + group) the spiral's
    radii, radii squared, cosines, sines and inverse pdfs, the first ``counts[level]`` of each
    row; ``counts``, ``limit``, ``blocks``, ``block`` and ``fp_reach`` the plan each pixel's
    count follows (``_burley_tile``); ``group`` (H, W) each pixel's group, or (1, 1) for one
    group; ``reach`` (3,) float64,
    16 d_c per channel (0: the channel keeps its light; so does a channel whose reach times the
    pixel's scale is at most one pixel); ``rot_cos``/``rot_sin`` the per-pixel rotation as
    NumPy computed it for rows ``rot_y0``.. and columns ``rot_x0``.. (every pixel of ``ok`` in
    rows y_lo - radius .. y_hi + radius), or
    (1, 1) holding 1 and 0 for none; ``ids`` flat object ids (int32 or int64), or one 0 for
    none.

    A pixel's scale (pixels per scene unit) is ``scale_of`` its depth and ``cam``.
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
            light, packed, packed_area, py0, px0, ok, cam, ids, group, tables, counts, limit, blocks, block, fp_reach,
            rot_cos, rot_sin, rot_y0, rot_x0, inv3d, reach, ya, yb, xa, xb, buf,
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
                k = r > 0 and ok[y, x] and np.float64(scale_of(depth[y, x], cam)) * min(reach[c], extents[g]) >= min_px
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
                        xo = u64(lo)
                        no = u64(lo + dx)
                        bo = u64(lo + dx - xa)
                        io = u64(lo - x0)
                        for t in range(hi - lo):
                            ut = u64(t)
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


@njit(cache=True, parallel=True, error_model="numpy")
def burley_block_sums(light, ok, depth, y0, x0, block, s1, s2, n, nearest):
    """core.techniques.burley.adaptive.block_sums on the compiled backend, to the bit: per block
    of ``block`` x ``block`` pixels from frame row ``y0`` and column ``x0`` (``n``'s shape), the
    float64 sums of the light (``s1``) and of its squares (``s2``) per channel over the pixels of
    ``ok``, their number (``n``) and their least depth (``nearest``, +inf for none). The sums
    take the pixels in the reference's order (row, then column, within the block) without
    fastmath: the same roundings."""
    h, w = ok.shape
    ny, nx = n.shape
    for by in prange(ny):
        for bx in range(nx):
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            q0 = 0.0
            q1 = 0.0
            q2 = 0.0
            count = 0.0
            least = INF
            for dy in range(block):
                y = y0 + by * block + dy
                for dx in range(block):
                    x = x0 + bx * block + dx
                    if y < h and x < w and ok[y, x]:
                        v0 = np.float64(light[y, x, 0])
                        v1 = np.float64(light[y, x, 1])
                        v2 = np.float64(light[y, x, 2])
                        count += 1.0
                        least = min(least, depth[y, x])
                    else:
                        v0 = 0.0
                        v1 = 0.0
                        v2 = 0.0
                    a0 += v0
                    a1 += v1
                    a2 += v2
                    q0 += v0 * v0
                    q1 += v1 * v1
                    q2 += v2 * v2
            s1[by, bx, 0] = a0
            s1[by, bx, 1] = a1
            s1[by, bx, 2] = a2
            s2[by, bx, 0] = q0
            s2[by, bx, 1] = q1
            s2[by, bx, 2] = q2
            n[by, bx] = count
            nearest[by, bx] = least
