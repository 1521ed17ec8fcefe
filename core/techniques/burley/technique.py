"""Christensen-Burley normalized diffusion gathered along a golden-angle spiral, in NumPy.

Christensen & Burley, Pixar memo 15-04 (2015); Golubev, SIGGRAPH 2018 course, and the
estimator shared by HDRP, EEVEE Next and Unreal (docs/references.md §1). For each pixel of
the mask, n samples:

- radius r_i = P^{-1}(u_i) d_max with u_i = (i + 0.5) / n (stratified: never 0 or 1) and the
  closed-form inverse CDF of the widest channel, truncated at 16 d_max;
- angle i x pi (3 - sqrt 5), plus an optional per-pixel rotation (noise instead of banding);
- the sample point, r_i pixels-per-unit away on screen, is point-sampled (interpolated depth
  leaks light across edges);
- weight per channel w_ic = R_c(r'_i) / pdf(r_i), with r'_i = sqrt(r_i^2 + dz^2) the 3-D
  distance (depth jumps) and pdf the area density of the widest channel's profile;
- samples off the image, off the mask, from another object (object id) or background get no
  weight; out_c = A_c sum_i w_ic E_ic / sum_i w_ic (self-normalized per channel, so rejected
  samples renormalize instead of darkening; the sum is guarded);
- except a sample on something nearer the camera than its pixel (another object, a pixel off
  the mask): the surface there is hidden, not absent, and the sample counts the pixel's own
  light at the pixel's depth, with its surface (docs/references.md §1: measured on the fidelity
  suite, where the walk carries light from behind occluders and from the surface that meets a
  floor in front of it).

A pixel whose footprint (16 d_max in pixels) is at most one pixel is left as it is, as EEVEE
Next does; so is each channel whose own footprint is (a channel far narrower than a pixel).

With ``adaptive`` (the default) n is a pixel's own: at most ``n_samples``, fewer where the light
under its footprint hardly varies or the footprint covers few pixels, each count with its own
stratified spiral (``core.techniques.burley.adaptive``, docs/references.md §21), for the quality
of ``n_samples`` fixed samples; ``sample_counts`` gives each pixel's n. ``adaptive=False`` takes
``n_samples`` everywhere.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...base import arrays
from ...compute import backend
from ...compute.bounds import gather_bound
from ...optics import pixels
from ...optics.energy import apply_energy, energy_inputs
from ...optics.profiles import TRUNCATION, burley_icdf
from ...optics.surface import MIN_VIEW_COSINE, surface_area, surface_area_args
from ...scene.extent import group_extents, object_extent
from ...scene.passes import THICKNESS
from ...scene.scene import Camera
from ..params import ENERGY_PARAM
from ..spec import CALIBRATE_MAPPING, Param, Technique, profile_footprint
from . import adaptive as adaptive_counts


def _kernels():
    """This package's compiled kernels (``_kernels.py``), loaded on first use."""
    return backend.kernels(__package__)


GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))
MAX_SAMPLES = 4096

_BLOCK_ELEMENTS = 1 << 16


def spiral(n_samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(unit radii r_i / d, angles, r_i / pdf ratio factor) of the stratified golden-angle spiral.

    The third array is r / (e^{-r} + e^{-r/3}) at d = 1: the sample's inverse area pdf up to a
    constant (pdf_area(r) = (e^{-r} + e^{-r/3}) / (8 pi r)), which cancels in the normalization.
    """
    u = (np.arange(n_samples) + 0.5) / n_samples * _TRUNCATION_CDF
    r = burley_icdf(u, 1.0)
    angles = np.arange(n_samples) * GOLDEN_ANGLE
    inv_pdf = r / (np.exp(-r) + np.exp(-r / 3.0))
    return r, angles, inv_pdf


_TRUNCATION_CDF = 1.0 - 0.25 * math.exp(-TRUNCATION) - 0.75 * math.exp(-TRUNCATION / 3.0)


def spiral_su(n_samples: int, d_max: float, reach_su: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(radii in scene units, angles, relative inverse pdf) of the stratified spiral of
    ``spiral``, truncated at ``reach_su`` (at most 16 ``d_max``; less when the object is
    smaller, ``core.scene.extent``).

    The radii follow the widest channel's profile restricted to [0, reach]: r_i = P^{-1}(u_i
    P(reach)). The estimator is self-normalized, so restricting where it samples changes no
    weight, only where the samples go. For reach much smaller than d the profile's radial pdf
    is flat (P(r) = r / 2d - r^2 / 6d^2 + ...) and the radii are uniform in [0, reach]. The
    inverse pdf is scaled by its largest value: constants cancel, and d_max may be far larger
    than float32 holds.
    """
    t = min(reach_su / d_max, TRUNCATION)
    c = -0.25 * math.expm1(-t) - 0.75 * math.expm1(-t / 3.0)  # P(t), accurate for tiny t too
    u = (np.arange(n_samples) + 0.5) / n_samples * c
    # Below 1e-6 the closed-form inverse loses its digits (1 - xi rounds to 1); P is linear there.
    r_unit = 2.0 * u if c < 1e-6 else burley_icdf(u, 1.0)
    r_su = r_unit * d_max
    angles = np.arange(n_samples) * GOLDEN_ANGLE
    inv_pdf = r_su / (np.exp(-r_unit) + np.exp(-r_unit / 3.0))
    return r_su, angles, inv_pdf / inv_pdf.max()


def _rotation(idx: np.ndarray, seed: int) -> np.ndarray:
    """A per-pixel angle in [0, 2 pi) from an integer hash of the pixel index and the seed."""
    x = (idx.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)) ^ np.uint64(seed & 0xFFFFFFFF)
    x ^= x >> np.uint64(31)
    x *= np.uint64(0xBF58476D1CE4E5B9)
    x ^= x >> np.uint64(29)
    return (x >> np.uint64(40)).astype(np.float32) * np.float32(2.0 * math.pi / (1 << 24))


#: The clean-up (``smooth_px``) applies where the footprint (16 d_max) spans at least this many
#: pixels: there the profile is at least 2 px wide (d >= 2 px), so a 3 x 3 average removes
#: sampling noise without widening anything the profile resolves.
SMOOTH_MIN_FOOTPRINT_PX = 32.0


def _smooth(result, idx_all, shape, px_per_unit, d, extent_su, zkey, idflat, radius: int) -> np.ndarray:
    """Edge-aware clean-up of the per-pixel rotation's noise, per channel: where a channel's
    footprint (16 d_c, or the object's extent ``extent_su`` when smaller, as the spiral's reach)
    spans at least ``SMOOTH_MIN_FOOTPRINT_PX``, a gathered pixel takes the mean
    of that channel over the gathered pixels within ``radius`` (a (2 radius + 1)^2 box) that belong
    to its object and lie within d_c of its depth (the profile's own scale: a larger jump is
    another surface). The scattered light is smooth at these footprints while the rotation's
    noise is independent from pixel to pixel, so the box divides the noise by up to 2 radius + 1
    and changes the profile's spread by less than a pixel."""
    h, w = shape
    f32 = np.float32
    r = radius
    px = px_per_unit[idx_all].astype(np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        keep = [px * np.minimum(TRUNCATION * float(dc), extent_su) >= SMOOTH_MIN_FOOTPRINT_PX for dc in d]
    if not any(k.any() for k in keep):
        return result
    val = np.zeros((h + 2 * r, w + 2 * r, 3), f32)
    valid = np.zeros((h + 2 * r, w + 2 * r), bool)
    zz = np.full((h + 2 * r, w + 2 * r), np.inf, f32)
    ii = np.full((h + 2 * r, w + 2 * r), -1, np.int64)
    ys, xs = np.divmod(idx_all, w)
    val[ys + r, xs + r] = result
    valid[ys + r, xs + r] = True
    zz[r : r + h, r : r + w] = zkey[: h * w].reshape(h, w)
    if idflat is not None:
        ii[r : r + h, r : r + w] = idflat.reshape(h, w)
    out = result.copy()
    for c in range(3):
        if not keep[c].any():
            continue
        cy, cx = ys[keep[c]] + r, xs[keep[c]] + r
        zc, ic = zz[cy, cx], ii[cy, cx]
        tol = f32(min(float(d[c]), 3.0e38))
        total = np.zeros(cy.size, np.float64)
        count = np.zeros(cy.size, np.float64)
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                ny, nx = cy + dy, cx + dx
                wgt = valid[ny, nx] & (ii[ny, nx] == ic) & (np.abs(zz[ny, nx] - zc) <= tol)
                total += np.where(wgt, val[ny, nx, c], 0.0)
                count += wgt
        out[keep[c], c] = (total / np.maximum(count, 1.0)).astype(f32)
    return out


def _check_bound(args: dict, reference: np.ndarray) -> np.ndarray:
    """Check mode's bound (``backend.checked``): the weighted sum and the sum of the weights, n
    samples each, within the profile's reach."""
    d = float(np.max(np.asarray(args["d_su"], np.float64)))
    return gather_bound(args, reference, 2 * int(args["n_samples"]), TRUNCATION * d)


@backend.checked(bound=_check_bound)
def burley(
    *,
    diffuse,
    albedo,
    depth,
    mask,
    camera: Camera,
    d_su,
    object_id=None,
    n_samples: int = 32,
    adaptive: bool = True,
    random_rotation: bool = True,
    seed: int = 0,
    smooth_px: int = 1,
    albedo_mode: str = "post",
    energy: str = "object",
    subsurface_method: str | None = None,
    normal=None,
    position=None,
    thickness=None,
    lights=(),
    mfp_su=None,
    thickness_distance_su: float = 0.0,
    thickness_convention: str = "translucency",
    lamps_behind: bool = True,
    plan_d_su=None,
) -> np.ndarray:
    """Burley normalized diffusion of the diffuse light, with the albedo applied.

    ``diffuse`` (H, W, 3) diffuse light without the BSDF colour; ``albedo`` (H, W, 3);
    ``depth`` (H, W) planar view depth (1e10 background); ``mask`` (H, W) bool; ``d_su`` the
    profile's d per channel (R, G, B) in scene units (``core.pipeline.mapping.burley_d``); ``object_id``
    (H, W) optional: samples from another id are rejected. ``n_samples`` 1..4096.
    ``energy``: how the light on the mask follows Cycles' ``subsurface_method``
    (``core.optics.energy.apply_energy``; None: no method, no change): "object" (default) spread over
    the view angles with each channel's total kept, times a finite object's light (with
    ``thickness``, ``normal``, ``position``, ``lights``, ``mfp_su`` and ``thickness_distance_su``:
    what leaves through its far side and what comes through it), "view" the spread alone,
    "lambert" the passes' light as it is.
    ``plan_d_su`` (R, G, B, scene units; None: ``d_su``): the d the adaptive plan reads its
    footprints from (``_plan``), not a user's setting: a fitted material's own d, so that the
    counts stay those of the material whatever d's fitted scale (``core.pipeline.mapping``, and
    ``core/study/fit.py``, which tries many d with one plan).
    Returns float32 (H, W, 3): albedo x scattered light on the mask, albedo x diffuse elsewhere.
    """
    out = _gather(
        diffuse=diffuse,
        albedo=albedo,
        depth=depth,
        mask=mask,
        camera=camera,
        d_su=d_su,
        object_id=object_id,
        n_samples=n_samples,
        adaptive=adaptive,
        random_rotation=random_rotation,
        seed=seed,
        smooth_px=smooth_px,
        albedo_mode=albedo_mode,
        plan_d_su=plan_d_su,
    )
    return apply_energy(out, **energy_inputs(locals()))


def _gather(
    *,
    diffuse,
    albedo,
    depth,
    mask,
    camera: Camera,
    d_su,
    object_id,
    n_samples: int,
    adaptive: bool,
    random_rotation: bool,
    seed: int,
    smooth_px: int,
    albedo_mode: str,
    plan_d_su=None,
) -> np.ndarray:
    """``burley`` without the entry energy."""
    if not isinstance(camera, Camera):
        raise ValueError(f"camera: expected a core.scene.scene.Camera, got {type(camera).__name__}")
    arrays.check_albedo_mode(albedo_mode)
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)) or not 1 <= n_samples <= MAX_SAMPLES:
        raise ValueError(f"n_samples: expected an integer in 1..{MAX_SAMPLES}, got {n_samples!r}")
    d = arrays.rgb_lengths(d_su, "d_su")
    e = arrays.image(diffuse, "diffuse")
    shape = e.shape[:2]
    a = arrays.image(albedo, "albedo")
    z = arrays.image(depth, "depth", None)
    ids = None if object_id is None else arrays.image(object_id, "object_id", None)
    arrays.same_size(shape, albedo=a, depth=z, object_id=ids)
    m = arrays.mask_array(mask, shape)

    dmax = float(d.max())
    plan_dmax = _plan_dmax(plan_d_su, dmax)
    if dmax > 0 and backend.active() == "numba":
        return _compiled(
            e, a, z, m, ids, camera, int(n_samples), bool(adaptive), d, random_rotation, seed, int(smooth_px),
            albedo_mode, plan_dmax,
        )  # fmt: skip
    base = a * e
    ok, scale = _gathered_pixels(e, a, z, m, ids, camera, dmax)
    if scale is None:
        return base
    pre, post = arrays.split_albedo(a, albedo_mode)
    light = e if pre is None else pre * e
    plan = _plan(light, ok, z, camera, plan_dmax, int(n_samples), adaptive)
    result, idx_all, groups = _reference(light, z, ok, ids, camera, scale, d, plan, plan_dmax, random_rotation, seed)
    return _smoothed(result, idx_all, groups, shape, scale, d, z, ids, int(smooth_px), post, base)


def _gathered_pixels(e, a, z, m, ids, camera: Camera, dmax: float):
    """(ok, scale): the pixels the NumPy gather reads (on the mask, finite inputs, in front of the
    background, a footprint wider than one pixel) and the pixels per scene unit; scale is None
    when there is no such pixel (nothing to gather)."""
    ok = m & arrays.finite_pixels(e, a, z) & (z > 0) & (z < arrays.BACKGROUND_DEPTH)
    if ids is not None:
        ok &= np.isfinite(ids)
    if dmax <= 0 or not ok.any():
        return ok, None
    scale = camera.pixels_per_unit(z)
    # Footprint of at most one pixel: nothing to gather (EEVEE Next skips these pixels).
    with np.errstate(over="ignore"):
        ok &= TRUNCATION * dmax * scale > 1.0
    return ok, (scale if ok.any() else None)


def _plan(light, ok, z, camera, plan_dmax: float, n: int, adaptive: bool) -> adaptive_counts.Plan:
    """The samples each pixel takes (``core.techniques.burley.adaptive``): the same plan for
    both backends. Its footprints are read from ``plan_dmax`` (``_plan_dmax``), the spiral's from
    d: a fit tries many d with one plan, and apply gives the fitted material that plan."""
    if not adaptive:
        return adaptive_counts.fixed(n)
    return adaptive_counts.plan(light, ok, z, camera, TRUNCATION * plan_dmax, n)


def _plan_dmax(plan_d_su, dmax: float) -> float:
    """The largest d the adaptive plan reads its footprints from: ``plan_d_su``'s (``burley``), or
    ``dmax`` (the gather's) when it is None."""
    if plan_d_su is None:
        return dmax
    return float(arrays.rgb_lengths(plan_d_su, "plan_d_su").max())


def sample_counts(
    *,
    diffuse,
    albedo,
    depth,
    mask,
    camera: Camera,
    d_su,
    object_id=None,
    n_samples: int = 32,
    adaptive: bool = True,
    albedo_mode: str = "post",
    plan_d_su=None,
    **_ignored,
) -> np.ndarray:
    """The samples ``burley`` called with these arguments takes at each pixel, int32 (H, W): its
    count of the plan (``core.techniques.burley.adaptive``; ``n_samples`` everywhere when not
    ``adaptive``) on the pixels it gathers, 0 on those it leaves as they are (off the mask, a
    footprint of at most one pixel). Any other keyword (``seed``, ``energy`` ...) is accepted and
    changes nothing: the counts depend on these inputs only. Their mean over the gathered pixels
    is the samples per pixel actually taken (``make bench``)."""
    d = arrays.rgb_lengths(d_su, "d_su")
    e = arrays.image(diffuse, "diffuse")
    a = arrays.image(albedo, "albedo")
    z = arrays.image(depth, "depth", None)
    ids = None if object_id is None else arrays.image(object_id, "object_id", None)
    m = arrays.mask_array(mask, e.shape[:2])
    counts = np.zeros(e.shape[:2], np.int32)
    dmax = float(d.max())
    plan_dmax = _plan_dmax(plan_d_su, dmax)
    ok, scale = _gathered_pixels(e, a, z, m, ids, camera, dmax)
    if scale is None:
        return counts
    pre, _ = arrays.split_albedo(a, albedo_mode)
    plan = _plan(e if pre is None else pre * e, ok, z, camera, plan_dmax, int(n_samples), adaptive)
    groups = group_extents(ok, scale, ids) if ids is not None else [(np.flatnonzero(ok), object_extent(ok, scale))]
    for group, extent_su in groups:
        reach_su = adaptive_counts.footprint_reach(plan_dmax, extent_su)
        level = plan.levels(group, scale.ravel()[group].astype(np.float64) * reach_su, ok.shape[1])
        counts.ravel()[group] = plan.counts[level]
    return counts


def _reference(light, z, ok, ids, camera, scale, d, plan, plan_dmax, random_rotation, seed):
    """The NumPy reference of the gather: (each pixel's scattered light before the albedo and
    the clean-up (rows in the order of ``idx_all``), ``idx_all``: the flat indices of the
    pixels that take part (``ok``), ``groups``: the (pixels, extent) of each object), the
    pixels gathered ``_BLOCK_ELEMENTS`` samples at a time (``_gather_block``), each with the
    spiral of its count (``plan``, ``core.techniques.burley.adaptive``; its footprints at
    ``plan_dmax``, ``_plan``)."""
    h, w = ok.shape
    f32 = np.float32
    dmax = float(d.max())
    # The spiral reaches 16 d_max, or the object's extent when that is smaller (core.scene.extent):
    # beyond it there is nothing of the object to gather, so the result is unchanged by the
    # bound and continuous as d grows; every backend gets the bounded spiral.
    # One group without index arrays when there are no object ids (core.scene.extent.object_extent).
    groups = group_extents(ok, scale, ids) if ids is not None else [(None, object_extent(ok, scale))]
    packed, zfront = _packed(light, z, ok)
    frame = _Frame(
        shape=(h, w),
        packed=packed,
        items=packed.view(np.dtype((np.void, 16))).ravel(),
        zfront=zfront,
        aflat=np.append(surface_area(z, ok, camera).ravel(), f32(0.0)),
        idflat=None if ids is None else np.rint(ids).astype(np.int64).ravel(),
        sflat=scale.ravel(),
        d=d,
        inv3d=_inv3d(d),
        reach_c=TRUNCATION * d,  # each channel's own footprint, scene units (float64: d may be huge)
        seed=seed if random_rotation else None,
    )
    if groups[0][0] is None:
        groups = [(np.flatnonzero(ok), groups[0][1])]
    idx_all = np.concatenate([g for g, _ in groups])
    result = np.empty((idx_all.size, 3), f32)
    start = 0
    for group, extent_su in groups:
        reach_su = adaptive_counts.footprint_reach(dmax, extent_su)
        plan_reach = adaptive_counts.footprint_reach(plan_dmax, extent_su)
        level = plan.levels(group, frame.sflat[group].astype(np.float64) * plan_reach, w)
        for k, n in enumerate(plan.counts.tolist()):
            rows = np.flatnonzero(level == k) if plan.counts.size > 1 else np.arange(group.size)
            if not rows.size:
                continue
            r_su64, angles, inv_pdf = spiral_su(n, dmax, reach_su)
            r_su = r_su64.astype(f32)
            tables = (r_su, r_su * r_su, np.cos(angles).astype(f32), np.sin(angles).astype(f32), inv_pdf.astype(f32))
            part = np.empty((rows.size, 3), f32)
            idx = group[rows]
            arrays.for_blocks(
                rows.size,
                max(128, _BLOCK_ELEMENTS // n),
                lambda lo, hi, t=tables, idx=idx, part=part: _gather_block(frame, idx[lo:hi], *t, part[lo:hi]),
            )
            result[start + rows] = part
        start += group.size
    return result, idx_all, groups


class _Frame(NamedTuple):
    """What ``_gather_block`` reads of the frame (``_reference``): its (h, w); ``packed``
    (``_packed``; ``items``: its rows as 16-byte items) and ``zfront``; the surface each pixel
    covers (``aflat``, ``surface_area``, 0 at the sentinel); the object ids (``idflat``, or
    None); pixels per scene unit (``sflat``); the lengths ``d``, ``_inv3d(d)`` and the
    footprints ``reach_c``; the rotations' seed (None: no rotation)."""

    shape: tuple
    packed: np.ndarray
    items: np.ndarray
    zfront: np.ndarray
    aflat: np.ndarray
    idflat: np.ndarray | None
    sflat: np.ndarray
    d: np.ndarray
    inv3d: np.ndarray
    reach_c: np.ndarray
    seed: int | None


def _packed(light, z, ok):
    """(packed, zfront): each pixel as one 16-byte item (r, g, b, depth key), plus a last item
    (0, 0, 0, inf) that samples off the image or from another object read, so that one gather
    per sample fetches colour and depth; and the depth of each pixel that takes no part."""
    h, w = ok.shape
    f32 = np.float32
    # Pixels that take no part have colour 0 (a NaN times a zero weight would still be NaN) and
    # key +inf, so that their weight is exactly 0 (e^-inf = 0, r / inf = 0).
    packed = np.empty((h * w + 1, 4), f32)
    rec = packed.view(np.dtype({"names": ["rgb", "key"], "formats": [arrays.RGB_ITEM, f32], "offsets": [0, 12]}))
    rec = rec.ravel()
    rec["rgb"][: h * w] = arrays.pixel_rows(light)
    rec["rgb"][np.flatnonzero(~ok)] = arrays.ZERO_RGB
    rec["key"][: h * w] = z.ravel()
    rec["key"][np.flatnonzero(~ok)] = np.inf
    packed[h * w] = (0.0, 0.0, 0.0, np.inf)
    # The depth of each pixel that takes no part, +inf where it does or has no positive depth (and
    # for the off-image sentinel): a sample there is on something in front of its pixel where this
    # is nearer than the pixel (``_gather_block``).
    zfront = np.full(h * w + 1, np.inf, f32)
    apart = (~ok & (z > 0)).ravel()  # NaN depths compare false
    zfront[: h * w][apart] = np.asarray(z, f32).ravel()[apart]
    return packed, zfront


def _sample_pixels(idx, s, shape, r_su, cos_a, sin_a, seed):
    """The flat pixel of each sample (B, n) of the pixels ``idx`` (``s``: their pixels per
    scene unit), the spiral's radii ``r_su`` and angles (rotated per pixel unless ``seed`` is
    None), rounded to the nearest pixel; h x w (the sentinel item) off the image."""
    h, w = shape
    f32 = np.float32
    x0 = (idx % w).astype(f32)
    y0 = (idx // w).astype(f32)
    rad_px = s[:, None] * r_su[None, :]
    if seed is not None:
        phi = _rotation(idx, seed)[:, None]
        ca = np.cos(phi) * cos_a - np.sin(phi) * sin_a
        sa = np.sin(phi) * cos_a + np.cos(phi) * sin_a
    else:
        ca, sa = cos_a[None, :], sin_a[None, :]
    xs = rad_px * ca
    xs += x0[:, None]
    np.rint(xs, out=xs)
    ys = np.multiply(rad_px, sa, out=rad_px)
    ys += y0[:, None]
    np.rint(ys, out=ys)
    # Off the image: the sentinel item. Clipping and comparing is cheaper than four comparisons.
    xc = np.clip(xs, f32(0.0), f32(w - 1))
    yc = np.clip(ys, f32(0.0), f32(h - 1))
    outside = xc != xs
    outside |= yc != ys
    j = yc.astype(np.intp)
    j *= w
    j += xc.astype(np.intp)
    np.copyto(j, h * w, where=outside)
    return j


def _gather_block(frame, idx, r_su, r2, cos_a, sin_a, inv_pdf, out):
    """The scattered light (B, 3) of the pixels ``idx`` into ``out``: ``frame`` (``_reference``'s
    per-frame arrays) gathered at their samples (``_sample_pixels``) with the spiral's tables."""
    f32 = np.float32
    packed, aflat, idflat = frame.packed, frame.aflat, frame.idflat
    zkey = packed[:, 3]
    sentinel = frame.shape[0] * frame.shape[1]
    b, n = idx.size, r_su.size
    s = frame.sflat[idx]
    j = _sample_pixels(idx, s, frame.shape, r_su, cos_a, sin_a, frame.seed)
    zc = zkey[idx][:, None]
    # Samples on something nearer the camera that takes no part (another object, a pixel off
    # the mask): the surface there is hidden, not absent; such a sample stands for the pixel's
    # own light, at its depth and with its surface (docs/references.md §1).
    hidden = frame.zfront[j] < zc
    if idflat is not None:
        other = idflat[np.minimum(j, sentinel - 1)] != idflat[idx][:, None]
        hidden |= other & (zkey[j] < zc)
        np.copyto(j, sentinel, where=other)
    g = np.take(frame.items, j).view(f32).reshape(b, n, 4)
    surface = np.take(aflat, j)
    if hidden.any():
        g[hidden] = packed[np.broadcast_to(idx[:, None], hidden.shape)[hidden]]
        surface[hidden] = np.broadcast_to(aflat[idx][:, None], hidden.shape)[hidden]
    rp = np.subtract(g[..., 3], zc)
    rp *= rp
    rp += r2[None, :]
    np.sqrt(rp, out=rp)
    # R_c(r') / pdf_area(r) up to constants: (e^{-r'/d} + e^{-r'/3d}) / r' x r / f(r).
    ratio = np.maximum(rp, f32(1e-30))
    np.divide(inv_pdf[None, :], ratio, out=ratio)
    ratio *= surface  # the surface the sample's pixel covers
    e3 = np.empty_like(rp)
    wgt = np.empty_like(rp)
    d, inv3d, reach_c = frame.d, frame.inv3d, frame.reach_c
    ones = np.ones(n, f32)  # for the sums over the samples
    for c in range(3):
        centre = packed[idx, c]
        if d[c] <= 0:
            out[:, c] = centre
            continue
        np.multiply(rp, -inv3d[c], out=e3)
        np.exp(e3, out=e3)
        np.multiply(e3, e3, out=wgt)
        wgt *= e3
        wgt += e3
        wgt *= ratio
        den = wgt @ ones
        wgt *= g[..., c]
        num = wgt @ ones
        with np.errstate(over="ignore"):
            small = reach_c[c] * s <= 1.0  # this channel's footprint <= 1 px
        keep = small | (den <= f32(1e-30))
        out[:, c] = np.where(keep, centre, num / np.where(keep, f32(1.0), den))


def _smoothed(result, idx_all, groups, shape, scale, d, z, ids, smooth_px, post, out):
    """The gathered pixels' scattered light ``result`` (rows in ``idx_all`` order), cleaned up
    (``_smooth``, when ``smooth_px`` > 0), times the albedo ``post``, written into ``out``."""
    if smooth_px > 0:
        extent = np.concatenate([np.full(g.size, e, np.float64) for g, e in groups])
        idflat = None if ids is None else np.rint(ids).astype(np.int64).ravel()
        result = _smooth(result, idx_all, shape, scale.ravel(), d, extent, z.ravel(), idflat, smooth_px)
    flat = arrays.pixel_rows(out)
    res = arrays.as_rows(arrays.pixel_rows(post)[idx_all])
    res *= result
    flat[idx_all] = res.reshape(-1).view(arrays.RGB_ITEM)
    return out


def _inv3d(d: np.ndarray) -> np.ndarray:
    """exp(-r'/(3 d_c)) per channel as the factor 1 / (3 d_c); a channel with d_c = 0 keeps its
    light (its footprint). At least the smallest normal float32 (a d beyond float32 would round
    it to 0), so that a sample with r' = inf (off the object) still gets e^-inf = 0, never
    inf x 0 = NaN."""
    return np.array([max(1.0 / (3.0 * v), 1e-37) if v > 0 else 0.0 for v in d], np.float32)


def _compiled(e, a, z, m, ids, camera, n, adaptive, d, random_rotation, seed, smooth_px, albedo_mode, plan_dmax):
    """``_gather`` on the compiled backend: the pixels that take part in one pass over the frame
    (``pixels.compiled_pixels``, with the footprint rule), then the gather and the clean-up as
    one compiled kernel (``core.techniques.burley._kernels.burley_kernel``) over their bounding box, into the
    albedo x diffuse frame, with the NumPy code's tables: one bounded spiral per object and
    count of the plan (``spiral_su``, ``_plan``), the rotation, the object ids."""
    f32 = np.float32
    c = np.ascontiguousarray
    dmax = float(d.max())
    if ids is not None:
        m = m & np.isfinite(ids)
    out, ok, cam, box, extent_su, largest = pixels.compiled_pixels(e, a, z, m, camera, TRUNCATION * dmax, 1.0)
    if box is None:
        return out
    groups = [(None, extent_su)]
    if ids is not None:
        # One object on ``ok`` (the usual case; its ids are finite there): its extent is the one
        # ``compiled_pixels`` found, which ``group_extents`` would give it (the same box and the
        # same float32 scales), and one group needs no map of groups.
        on = ids[ok]
        if np.rint(on.min()) != np.rint(on.max()):
            zflat = z.ravel()  # the scales of each object's pixels only, not a frame of them
            groups = group_extents(ok, lambda idx: camera.pixels_per_unit(zflat[idx]), ids)
    pre, post = arrays.split_albedo(a, albedo_mode)
    light = e if pre is None else pre * e
    inv3d = _inv3d(d)
    reach_c = TRUNCATION * d
    plan = _plan(light, ok, z, camera, plan_dmax, n, adaptive)
    n_groups = len(groups)
    # Per count of the plan and group (row count x groups + group): radius, radius^2, cos, sin,
    # inverse pdf, the first ``plan.counts[count]`` of each row.
    tables = np.zeros((5, plan.counts.size * n_groups, n), f32)
    extents = np.empty(n_groups, np.float64)
    fp_reach = np.empty(n_groups, np.float64)  # the plan's footprint reach per group (its d)
    group_map = np.zeros((1, 1), np.int32)
    if n_groups > 1:
        group_map = np.zeros(ok.shape, np.int32)
    for k, (group, extent_su) in enumerate(groups):
        fp_reach[k] = adaptive_counts.footprint_reach(plan_dmax, extent_su)
        spiral_reach = adaptive_counts.footprint_reach(dmax, extent_su)
        for level, count in enumerate(plan.counts.tolist()):
            r_su64, angles, inv_pdf = spiral_su(count, dmax, spiral_reach)
            r_su = r_su64.astype(f32)
            row = (r_su, r_su * r_su, np.cos(angles).astype(f32), np.sin(angles).astype(f32), inv_pdf.astype(f32))
            tables[:, level * n_groups + k, :count] = row
        extents[k] = extent_su
        if n_groups > 1:
            group_map.ravel()[group] = k
    id_map = np.zeros(1, np.int32)
    if ids is not None:
        rounded = np.rint(ids)
        least, most = float(rounded.min()), float(rounded.max())  # NaN when any is: then int64
        small = rounded.size > 1 and np.iinfo(np.int32).min <= least and most <= np.iinfo(np.int32).max
        # The same ids as int32 where they fit, gathered 16 per 512-bit register instead of 8.
        id_map = rounded.astype(np.int32 if small else np.int64).ravel()
    z = c(z, dtype=f32)
    h = ok.shape[0]
    # The surface each pixel covers (``surface_area``), computed by ``burley_pack`` for the pixels
    # each band's samples reach.
    area_args = surface_area_args(camera, ok.shape, MIN_VIEW_COSINE)
    light = c(light, dtype=f32)
    post = c(post, dtype=f32)
    reach = np.asarray(reach_c, np.float64)
    tol = np.array([min(float(v), 3.0e38) for v in d], f32)
    radius = max(int(smooth_px), 0)
    # The rows and columns that hold pixels to gather (the 25 % mask case: a quarter of the work).
    r0, r1, c0, c1 = box
    # Bands of rows, each with the rotation of its pixels (and of the clean-up's margin) only:
    # two frames of cosines and sines would take more memory than the output. Each band's
    # samples read a packed copy of the rows they reach (light and depth key as one 16-byte
    # item per pixel, ``burley_pack``): one cache line per sample instead of two or three. Bands
    # without the rotation too, so that the packed copy stays small (a whole 4K frame's: 133 MB).
    band = _BAND_ROWS
    with np.errstate(over="ignore", invalid="ignore"):
        # How far a sample lands from its pixel: |rint(s r (cos, sin))| <= s r + 1/2.
        reach_px = largest * float(tables[0].max()) * 1.001 + 2.0
    reach_px = int(math.ceil(reach_px)) if math.isfinite(reach_px) else h
    margin = min(radius + reach_px, h)
    # Whole rows with object ids (the kernel finds a sample's id from its packed index). The
    # columns reach as far as the samples do (a frame may be wider than it is tall): a sample
    # reads what it lands on, which may be something in front of its pixel (``_burley_pixel``).
    side = min(radius + reach_px, ok.shape[1])
    px0 = 0 if ids is not None else max(c0 - side, 0)
    px1 = ok.shape[1] if ids is not None else min(c1 + side, ok.shape[1])
    packed = np.empty((min(band + 2 * margin, h), px1 - px0, 4), f32)
    packed_area = np.empty(packed.shape[:2], f32)
    rot_cos = np.ones((1, 1), f32)  # a rotation by 0 (cos 1, sin 0) leaves the spiral as it is
    rot_sin = np.zeros((1, 1), f32)
    packed_rows = (0, 0)  # the frame's rows the packed copy holds, from its first row
    for y_lo in range(r0, r1, band):
        y_hi = min(y_lo + band, r1)
        py0 = max(y_lo - margin, 0)
        py1 = min(y_hi + margin, h)
        rows = packed[: py1 - py0]
        rows_area = packed_area[: rows.shape[0]]
        # The rows this band shares with the previous one (2 margin of them) move to the top of
        # the copy instead of being packed again: packing computes each pixel's surface in
        # float64, and the shared rows grow with the samples' reach in pixels (a quarter of a 4K
        # frame's rows, 13 % of a 1080p one's, at the speed benchmark's footprint).
        kept = max(packed_rows[1] - py0, 0)
        if kept:
            start = py0 - packed_rows[0]
            rows[:kept] = packed[start : start + kept]
            rows_area[:kept] = packed_area[start : start + kept]
        if py0 + kept < py1:
            backend.run_kernel(
                _kernels().burley_pack,
                light,
                z,
                ok,
                *area_args,
                py0 + kept,
                px0,
                rows[kept:],
                rows_area[kept:],
            )
        packed_rows = (py0, py1)
        rot_y0 = rot_x0 = 0
        if random_rotation:
            rot_y0, rot_x0 = max(y_lo - radius, r0), c0
            phi = np.empty((min(y_hi + radius, r1) - rot_y0, c1 - c0), f32)
            backend.run_kernel(_kernels().burley_angles, ok, int(seed) & 0xFFFFFFFF, rot_y0, rot_x0, phi)
            rot_sin = np.sin(phi)  # NumPy's cosine and sine, as the reference's
            rot_cos = np.cos(phi, out=phi)
        backend.run_kernel(
            _kernels().burley_kernel,
            light, rows, rows_area, py0, px0, ok, cam, id_map, group_map, tables, plan.counts, plan.limit,
            plan.blocks, plan.block, fp_reach, rot_cos, rot_sin, rot_y0, rot_x0, inv3d, reach, extents, z, tol, radius,
            SMOOTH_MIN_FOOTPRINT_PX, post, y_lo, y_hi, c0, c1, out,
        )  # fmt: skip
    return out


#: Rows per band of the compiled gather (``_compiled``).
_BAND_ROWS = 512


#: Burley's spec (``core/techniques/spec.py``): at most 32 samples, the signature's default (EEVEE Next uses 16
#: per temporal sample, HDRP 20/40/80; docs/references.md §1), fewer where the plan allows
#: (``adaptive``, the default, ``core.techniques.burley.adaptive``); ``samples_per_pixel`` counts the
#: most a pixel takes (the plan reads the frame's light, which a cost model from parameters does not
#: have), ``sample_counts`` what each takes.
TECHNIQUE = Technique(
    name="burley",
    label="Burley",
    description="Christensen-Burley normalized diffusion, golden-angle spiral",
    citation="docs/references.md §1; Christensen & Burley 2015, Approximate Reflectance Profiles for Efficient "
    "Subsurface Scattering (Pixar technical memo)",
    function=burley,
    scatters=True,
    adds_light=False,
    # The finite-object part of the energy (core/optics/energy.py) when the passes hold them.
    optional_passes=("Normal", "Position", THICKNESS),
    passes=(
        "Combined",
        "Diffuse Direct",
        "Diffuse Indirect",
        "Diffuse Color",
        "Depth",
        "Material Index",
        "Object Index",
    ),
    params=(
        Param(
            "n_samples",
            "Samples",
            "Samples per pixel of the golden-angle spiral (the most a pixel takes when Adaptive Samples is on)",
            type=int,
            min=1,
            max=1024,
            soft_max=128,
        ),
        Param("random_rotation", "Random Rotation", "Rotate the spiral per pixel: noise instead of banding", type=bool),
        Param(
            "adaptive",
            "Adaptive Samples",
            "Fewer samples where the light under the profile hardly varies or the profile covers few pixels;"
            " Samples is then the most a pixel takes",
            type=bool,
        ),
        ENERGY_PARAM,
    ),
    qualities=({"n_samples": 8}, {"n_samples": 16}, {"n_samples": 32}, {"n_samples": 64}),
    default_quality=2,
    footprint=profile_footprint("n_samples"),
    calibration=CALIBRATE_MAPPING,
    fit=("gain", "d_scale"),
)
