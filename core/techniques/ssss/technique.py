"""Separable subsurface scattering (SSSS): two 1-D per-channel convolutions, in NumPy.

Jimenez et al., "Separable Subsurface Scattering", Computer Graphics Forum 34(6), 2015, and
its reference code (iryoku/separable-sss), docs/references.md §3. The diffuse light is
filtered horizontally, then vertically, with a kernel from ``core.optics.kernels``; the taps are laid
out in scene units and projected to pixels at each pixel's depth (``Camera.pixels_per_unit``:
perspective and orthographic), and read with linear interpolation along the pass.

Which pixels take part: only those of ``mask`` with finite inputs and a foreground depth. A tap
that lands on any other pixel (background, another object, NaN) gives nothing: its weight goes
to the centre pixel instead, as the reference code's "follow surface" does at depth jumps. So
light is neither taken from nor given to what the mask leaves out, and each channel's weights
still sum to one (no light is created or lost by the kernel).

"Follow surface": a tap whose depth differs from the centre's is blended towards the centre
colour by s = min(1, |dz| / (2 R)), R the kernel radius in scene units. The reference code uses
s = saturate(300 (1 / tan(fovy/2)) width |dz|), a screen-space constant; ours is the same idea
stated in scene units, independent of the field of view (a documented difference).

Weighting by surface (``weighting="surface"``, the default): the diffusion profile integrates
over the surface, a convolution sums over pixels, and a pixel seen at a grazing angle covers
more surface than one facing the camera (``core.optics.surface.surface_area``: cos a / cos, 1 on a plane
facing the camera's axis; at most ``MAX_SURFACE`` = 2 here, against Burley's 5). Each pass
weighs a tap's two samples by their pixels' surface relative to the centre pixel's and divides
by the total weight, so that the kernel's weights still sum to one; the part of a tap that
follow surface gives back to the centre keeps the centre's surface. Equal surfaces (a plane
facing the camera, any flat surface under an orthographic camera) give the paper's unweighted
result exactly. The row pass's results are weighted in the column pass by their own pixel's
surface. ``weighting="screen"`` is the paper's filter (docs/references.md §3 and §17).
"""

from __future__ import annotations

import numpy as np

from ...base import arrays
from ...compute import backend
from ...compute.bounds import gather_bound
from ...optics import pixels
from ...optics.energy import apply_energy, energy_inputs
from ...optics.kernels import SeparableKernel, bounded, check_taps, make_kernel
from ...optics.surface import surface_area, surface_area_args
from ...scene.extent import object_extent
from ...scene.passes import THICKNESS
from ...scene.scene import Camera
from ..params import ENERGY_PARAM
from ..spec import CALIBRATE_MAPPING, Param, Technique, profile_footprint


def _kernels():
    """This package's compiled kernels (``_kernels.py``), loaded on first use."""
    return backend.kernels(__package__)


#: Pixels (times taps) per block: small enough to stay in the cache, large enough to amortize calls.
_BLOCK_ELEMENTS = 1 << 16

#: How the taps are weighted: by the surface their pixels cover (the default), or by their
#: screen area, as the paper's filter (docs/references.md §3).
WEIGHTINGS = ("surface", "screen")

#: The largest surface weight of a tap's sample (``weighting="surface"``): the surface a pixel
#: covers over that of a pixel facing the camera, at most 2 (a view cosine of 0.5), where
#: Burley's gather takes up to 5. SSSS reads the surface at each tap's sample pixel, and its
#: outer taps are several pixels apart: a rim or a bevel one or two pixels wide weighing 5 turns
#: into bands as the taps cross it (the 80 px wax block of the fidelity suite); Burley's rotated
#: spiral and its clean-up average that out. Measured on the suite and the six scenes outside it
#: with the caps 5, 4, 3 and 2 (docs/references.md §3).
MAX_SURFACE = 2.0

#: A pixel and its right-hand neighbour along the pass, (r, g, b, key, r', g', b', key') as one
#: 32-byte item: one gather fetches both samples of a linearly interpolated tap with their depths.
_PAIR = np.dtype((np.void, 32))


_LAYOUT = np.dtype(
    {"names": ["rgb", "key"], "formats": [arrays.RGB_ITEM, np.float32], "offsets": [0, 12], "itemsize": 32}
)
_HALF = np.dtype((np.void, 16))
_NOTHING = np.array([(0.0, 0.0, 0.0, np.inf)], np.float32).view(_HALF)[0]


def _pairs(buf, length, key, rgb=None, zero=None, at=None, values=None) -> np.ndarray:
    """Pack pixels laid out in lines of ``length`` into ``buf`` (count + 1, 8) float32, as (count + 1,)
    ``_PAIR`` items.

    ``key`` (count,) in the pass's order; the colours are ``rgb`` (count,) 12-byte items
    (``arrays.pixel_rows``), with the pixels ``zero`` set to 0, or 0 everywhere but at the
    indices ``at``, which get ``values`` (12-byte items). The neighbour of a line's last pixel is
    (0, 0, 0, inf), so that it gives nothing (it is only read with weight 0). Whole 12- and
    16-byte items are copied: strided float copies of 3 or 4 columns are several times slower.
    """
    count = key.size
    rec = buf.view(_LAYOUT).ravel()
    if rgb is not None:
        rec["rgb"][:count] = rgb
        if zero is not None and zero.size:
            rec["rgb"][zero] = arrays.ZERO_RGB
    else:
        rec["rgb"] = arrays.ZERO_RGB
        rec["rgb"][at] = values
    rec["key"][:count] = key
    halves = buf.view(_HALF).reshape(count + 1, 2)
    halves[count] = _NOTHING
    halves[:count, 1] = halves[1:, 0]
    halves[length - 1 : count : length, 1] = _NOTHING
    return buf.view(_PAIR).ravel()


def _pass(packed, length, mask_idx, centre_key, scale, offsets, weights, result, area=None):
    """One 1-D pass along lines of ``length`` pixels (``packed`` from ``_pairs``), into ``result``.

    For the pixels ``mask_idx`` (flat indices in the pass's layout) with their ``centre_key``
    (depth x follow-surface factor; 0 when the key only tells valid 0 from invalid inf) and
    ``scale`` (pixels per scene unit): result (count, 3) = sum_k w_k (a0 p[i0] + a1 p[i0 + 1])
    + (1 - sum_k w_k (a0 + a1)) p[centre], a0 = (1 - f)(1 - g0), a1 = f (1 - g1), with
    g = min(1, |key - centre key|) the follow-surface blend. The zero-offset tap (f = 0, g = 0)
    only ever weights the centre, so it is left to the last term.

    With ``area`` (the surface weight of every pixel in the pass's layout, count + 1 values, the
    last a padding one): each sample's weight a is times rho = 1 + (area[i] - area[centre]) /
    area[centre] (the sample's surface over the centre's; exactly 1 where they are equal), the
    part that falls back to the centre keeps its weight (the centre's own surface), and the sum
    is divided by its total weight relative to the kernel's, D = wsum + sum_k w_k (a0 (rho0 - 1)
    + a1 (rho1 - 1)): result = (sum_k w_k (a0 rho0 p[i0] + a1 rho1 p[i1]) + (wsum - sum_k w_k (a0
    + a1)) p[centre]) x wsum / D. Equal surfaces give D = wsum and the unweighted result to the
    bit.
    """
    f32 = np.float32
    taps = offsets != 0
    o = offsets[taps].astype(f32)
    wt = weights[taps].astype(f32)
    wsum = weights.sum(axis=0).astype(f32)
    n = o.size
    # Weights per (tap, sample of the pair) in the order of the packed pair: (k0 i0, k0 i1, k1 i0, ...).
    wt2 = np.repeat(wt, 2, axis=0)
    cols = [np.ascontiguousarray(wt2[:, c]) for c in range(3)]
    count = mask_idx.size
    block = max(256, _BLOCK_ELEMENTS // max(n, 1))
    last = f32(length - 1)

    def run(start, stop):
        idx = mask_idx[start:stop]
        b = idx.size
        coord = idx % length
        line = idx - coord
        centre = np.take(packed, idx).view(f32).reshape(b, 8)[:, :3]
        if n == 0:
            result[start:stop] = centre * wsum
            return
        pos = scale[start:stop, None] * o[None, :]
        pos += coord.astype(f32)[:, None]
        np.clip(pos, f32(0.0), last, out=pos)
        fl = np.floor(pos)
        j = fl.astype(np.intp)
        j += line[:, None]
        f = pos
        f -= fl  # float32: subtracting the integer array would promote everything to float64
        g = np.take(packed, j).view(f32).reshape(b, n, 8)
        zc = centre_key[start:stop, None]
        # (1 - g) for both samples of each tap at once, then times the interpolation weights.
        a = np.empty((b, n, 2), f32)
        np.subtract(g[..., 3::4], zc[:, :, None], out=a)
        np.abs(a, out=a)
        np.subtract(f32(1.0), a, out=a)
        np.maximum(a, f32(0.0), out=a)
        lerp = np.empty((b, n, 2), f32)
        lerp[..., 1] = f
        np.subtract(f32(1.0), f, out=lerp[..., 0])
        a *= lerp
        a2 = a.reshape(b, 2 * n)
        res = result[start:stop]
        np.matmul(a2, wt2, out=res)
        np.subtract(wsum, res, out=res)
        res *= centre
        tmp = np.empty((b, n, 2), f32)
        tmp2 = tmp.reshape(b, 2 * n)
        if area is not None:
            # rho - 1 per sample (0 where its surface is the centre's), then a x (rho - 1): the
            # change of the total weight; a becomes a x rho.
            ac = area[idx]
            inv = f32(1.0) / ac
            rho = np.empty((b, n, 2), f32)
            rho[..., 0] = np.take(area, j)
            rho[..., 1] = np.take(area, j + 1)
            rho -= ac[:, None, None]
            rho *= inv[:, None, None]
            rho *= a
            total = rho.reshape(b, 2 * n) @ wt2
            a += rho
            total += wsum
        for c in range(3):
            np.multiply(a, g[..., c::4], out=tmp)
            res[:, c] += tmp2 @ cols[c]
        if area is not None:
            # Guarded: D >= the centre tap's weight, which may be 0 in a channel.
            good = total > f32(0.0)
            factor = np.divide(wsum, total, out=np.ones_like(total), where=good)
            res *= factor

    arrays.for_blocks(count, block, run)


def filter_1d(image, *, offsets_px, weights, axis: int, mask=None) -> np.ndarray:
    """One 1-D pass with fixed pixel offsets (no depth, no follow-surface): the building block of
    the separable convolution, exposed for checks against a direct 2-D convolution.

    ``image`` (H, W, 3); ``offsets_px`` (n,); ``weights`` (n,) or (n, 3); ``axis`` 1 filters
    along rows (horizontally), 0 along columns. Taps outside the image or the mask give their
    weight to the centre pixel. Returns float32 (H, W, 3).
    """
    img = arrays.image(image, "image")
    h, w, _ = img.shape
    o = np.asarray(offsets_px, dtype=np.float64)
    wt = np.asarray(weights, dtype=np.float64)
    if wt.ndim == 1:
        wt = np.repeat(wt[:, None], 3, axis=1)
    if o.ndim != 1 or wt.shape != (o.size, 3):
        raise ValueError(f"offsets_px/weights: expected (n,) and (n,) or (n, 3), got {o.shape} and {wt.shape}")
    if axis not in (0, 1):
        raise ValueError(f"axis: expected 0 (vertical) or 1 (horizontal), got {axis!r}")
    m = np.ones((h, w), bool) if mask is None else arrays.mask_array(mask, (h, w))
    key = np.where(m, np.float32(0.0), np.float32(np.inf)).astype(np.float32)
    out = np.array(img, dtype=np.float32, order="C")
    if axis == 0:
        img, key, m = img.transpose(1, 0, 2), key.T, m.T
    idx = np.flatnonzero(m)
    length = img.shape[1]
    buf = np.empty((h * w + 1, 8), np.float32)
    packed = _pairs(buf, length, np.ascontiguousarray(key).ravel(), rgb=arrays.pixel_rows(img))
    result = np.empty((idx.size, 3), np.float32)
    ones = np.ones(idx.size, np.float32)
    _pass(packed, length, idx, np.zeros(idx.size, np.float32), ones, o, wt, result)
    if axis == 0:
        idx = (idx % h) * w + idx // h
    arrays.pixel_rows(out)[idx] = result.view(arrays.RGB_ITEM).ravel()
    return out


def _check_bound(args: dict, reference: np.ndarray) -> np.ndarray:
    """Check mode's bound (``backend.checked``)."""
    kernel = args.get("kernel") or make_kernel(
        args["kernel_type"],
        args["n_taps"],
        d_su=args["d_su"],
        unit_su=args["unit_su"],
        falloff=args["falloff"],
        strength=args["strength"],
    )
    # Two passes of 2 samples per tap each (the second sums the first's rounded results).
    n = len(kernel)
    per_pass: float = 2 * n + 1
    if args.get("weighting", "surface") == "surface":
        # Weighted by surface (_pass), each pass's result is the weighted sum N times wsum / D,
        # D = wsum + sum_k w_k sum_j a_j (rho_j - 1). The weights a_j rho_j are the same float32
        # operations on both backends (the surface of the column pass is each pixel's own, not a
        # sum), so only the sums differ. N's terms are at most the largest light times D: N / D
        # is within 2 (2 n + 1) u of it, as before. D's 2 n terms have either sign and magnitudes
        # summing to at most sum w a (rho + 1) <= D + wsum, with D >= rho_min wsum (rho, a
        # surface over another, is at least rho_min): D is within 2 (2 n) (1 + 1 / rho_min) u of
        # itself, relatively. The quotient and its product: 2 roundings each.
        per_pass += 2 * n * (1 + 1 / _least_surface_ratio(args["camera"], reference.shape[:2])) + 2
    return gather_bound(args, reference, 2 * per_pass, kernel.radius_su)


def _least_surface_ratio(camera: Camera, shape: tuple[int, ...]) -> float:
    """The smallest ratio of two pixels' surface weights (``surface_area``, at most
    ``MAX_SURFACE``) in a frame of ``camera`` of ``shape`` (H, W): each is cos a / cos with
    cos <= 1 (at least cos a, the ray's angle a to the axis, smallest at the frame's corners)
    and at most MAX_SURFACE."""
    if camera.type == "ORTHO":
        least_axis = 1.0
    else:
        h, w = shape
        f = camera.focal_px
        cx, cy = camera.principal_point(w, h)
        u = max(abs(0.5 - cx), abs(w - 0.5 - cx)) / f
        v = max(abs(cy - 0.5), abs(cy - h + 0.5)) / f
        least_axis = 1.0 / float(np.sqrt(1.0 + u * u + v * v))
    return min(least_axis, 1.0) / MAX_SURFACE


@backend.checked(bound=_check_bound)
def ssss(
    *,
    diffuse,
    albedo,
    depth,
    mask,
    camera: Camera,
    kernel: SeparableKernel | None = None,
    kernel_type: str = "preintegrated",
    n_taps: int = 17,
    d_su=None,
    unit_su: float | None = None,
    falloff=None,
    strength=None,
    follow_surface: bool = True,
    albedo_mode: str = "post",
    weighting: str = "surface",
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
) -> np.ndarray:
    """Separable SSS of the diffuse light, with the albedo applied.

    ``diffuse`` (H, W, 3): diffuse light without the BSDF colour (Diffuse Direct + Indirect);
    ``albedo`` (H, W, 3): Diffuse Color; ``depth`` (H, W): planar view depth in scene units
    (1e10 background); ``mask`` (H, W) bool: the pixels that scatter; ``camera``: for the
    footprint in pixels. The kernel is ``kernel`` or built by ``core.optics.kernels.make_kernel`` from
    ``kernel_type``, ``n_taps`` (odd: 11, 17, 25), ``d_su`` (the Burley d per channel, scene
    units) and the artist parameters. ``albedo_mode`` "post": A x filter(E); "pre-post":
    sqrt(A) x filter(sqrt(A) E). ``weighting``: "surface" weighs each tap by the surface its
    pixel covers (module docstring), "screen" by its screen area (the paper's). ``energy``,
    ``subsurface_method`` and the inputs of the modelled energy (``normal``, ``position``,
    ``thickness``, ``lights``, ``mfp_su``, ``thickness_distance_su``): as
    ``core.techniques.burley.technique.burley``'s (``core.optics.energy.apply_energy``).

    Returns float32 (H, W, 3): on the mask, the filtered light times the albedo; elsewhere,
    albedo x diffuse unchanged (NaN/Inf pixels keep their value and give no light).
    """
    out = _filter(
        diffuse=diffuse,
        albedo=albedo,
        depth=depth,
        mask=mask,
        camera=camera,
        kernel=kernel,
        kernel_type=kernel_type,
        n_taps=n_taps,
        d_su=d_su,
        unit_su=unit_su,
        falloff=falloff,
        strength=strength,
        follow_surface=follow_surface,
        albedo_mode=albedo_mode,
        weighting=weighting,
    )
    return apply_energy(out, **energy_inputs(locals()))


def _filter(
    *,
    diffuse,
    albedo,
    depth,
    mask,
    camera: Camera,
    kernel: SeparableKernel | None,
    kernel_type: str,
    n_taps: int,
    d_su,
    unit_su: float | None,
    falloff,
    strength,
    follow_surface: bool,
    albedo_mode: str,
    weighting: str,
) -> np.ndarray:
    """``ssss`` without the entry energy."""
    if not isinstance(camera, Camera):
        raise ValueError(f"camera: expected a core.scene.scene.Camera, got {type(camera).__name__}")
    arrays.check_albedo_mode(albedo_mode)
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting: {weighting!r} is not one of {', '.join(WEIGHTINGS)}")
    e = arrays.image(diffuse, "diffuse")
    shape = e.shape[:2]
    a = arrays.image(albedo, "albedo")
    z = arrays.image(depth, "depth", None)
    arrays.same_size(shape, albedo=a, depth=z)
    m = arrays.mask_array(mask, shape)
    given = kernel
    artist = {"unit_su": unit_su, "falloff": falloff, "strength": strength}
    if kernel is None:
        check_taps(n_taps)
        if d_su is not None:
            arrays.rgb_lengths(d_su, "d_su")
        kernel = make_kernel(kernel_type, n_taps, d_su=d_su, **artist)
    elif not isinstance(kernel, SeparableKernel):
        raise ValueError(f"kernel: expected a core.optics.kernels.SeparableKernel, got {type(kernel).__name__}")

    built: SeparableKernel = kernel  # not None from here on (mypy cannot see it in the closure)

    def over_object(extent_su: float) -> SeparableKernel:
        # Taps beyond the object's extent would all land off it and give their weight back to the
        # centre (no scattering at all for a radius far too large): lay the kernel over the object
        # instead (core.scene.extent), rebuilt from its parameters, so that every backend filters with it.
        if built.radius_su <= extent_su:
            return built
        if given is None:
            return make_kernel(kernel_type, n_taps, d_su=d_su, radius_su=extent_su, **artist)
        return bounded(given, extent_su)

    if len(kernel) > 1 and backend.active() == "numba":
        return _compiled(e, a, z, m, camera, over_object, follow_surface, albedo_mode, weighting)
    base = a * e
    ok = m & arrays.finite_pixels(e, a, z) & (z > 0) & (z < arrays.BACKGROUND_DEPTH)
    if len(kernel) == 1 or not ok.any():
        return base
    scale = camera.pixels_per_unit(z)
    ok &= scale > 0
    if not ok.any():
        return base
    kernel = over_object(object_extent(ok, scale))
    # The surface each pixel covers (over the pixels that take part, before the one-pixel rule:
    # a pixel's neighbours on the material tell its slope whatever its kernel's size).
    area = np.minimum(surface_area(z, ok, camera), np.float32(MAX_SURFACE)) if weighting == "surface" else None
    # Pixels whose whole kernel is within one pixel would not change: skip them (EEVEE Next does).
    ok &= kernel.radius_su * scale > 0.5
    if not ok.any():
        return base
    pre, post = arrays.split_albedo(a, albedo_mode)
    light = e if pre is None else pre * e
    h, w = shape
    key = np.full(shape, np.inf, np.float32)
    np.multiply(z, _follow(kernel, follow_surface), out=key, where=ok)
    idx = np.flatnonzero(ok)
    buf = np.empty((h * w + 1, 8), np.float32)
    # Pass 1, along rows. Pixels that take no part give no light (a NaN times a zero weight would
    # still be NaN): their colour is 0 in the packed pairs.
    light_rows = arrays.pixel_rows(light)
    if 2 * idx.size >= h * w:
        packed = _pairs(buf, w, key.ravel(), rgb=light_rows, zero=np.flatnonzero(~ok))
    else:
        packed = _pairs(buf, w, key.ravel(), at=idx, values=light_rows[idx])
    once = np.empty((idx.size, 3), np.float32)
    area1 = None if area is None else np.append(area.ravel(), np.float32(1.0))
    _pass(packed, w, idx, key.ravel()[idx], scale.ravel()[idx], kernel.offsets_su, kernel.weights, once, area1)
    # Pass 2, along columns: the same on the transposed image (flat index x h + y), each pixel's
    # row result weighted by its own surface.
    area2 = None if area is None else np.append(np.ascontiguousarray(area.T).ravel(), np.float32(1.0))
    packed = _pairs(buf, h, key.T.ravel(), at=(idx % w) * h + idx // w, values=once.view(arrays.RGB_ITEM).ravel())
    del once
    idx_t = np.flatnonzero(ok.T)
    flat_of_t = (idx_t % h) * w + idx_t // h
    twice = np.empty((idx_t.size, 3), np.float32)
    centre_key, centre_scale = key.ravel()[flat_of_t], scale.ravel()[flat_of_t]
    _pass(packed, h, idx_t, centre_key, centre_scale, kernel.offsets_su, kernel.weights, twice, area2)
    del packed, buf
    twice *= arrays.as_rows(arrays.pixel_rows(post)[flat_of_t])
    out = base
    arrays.pixel_rows(out)[flat_of_t] = twice.view(arrays.RGB_ITEM).ravel()
    return out


def _follow(kernel: SeparableKernel, follow_surface: bool) -> np.float32:
    """Follow surface compares depths in units of 2 R: a pixel's key is z / (2 R) where it may
    give light, +inf elsewhere (so that it gives nothing); without it, 0 and +inf."""
    if not follow_surface:
        return np.float32(0.0)
    with np.errstate(over="ignore"):  # a vanishing radius: +inf, and no pixel passes the one-pixel rule
        return np.float32(1.0 / (2.0 * kernel.radius_su))


def _compiled(e, a, z, m, camera, over_object, follow_surface, albedo_mode, weighting):
    """The NumPy code above on the compiled backend: the pixels that take part in one pass over
    the frame (``pixels.compiled_pixels``), then both passes as one kernel
    (``core.techniques.ssss._kernels.ssss_kernel``, which applies the one-pixel rule and the keys itself), into
    the albedo x diffuse frame."""
    f32 = np.float32
    c = np.ascontiguousarray
    out, ok, cam, box, extent_su, _ = pixels.compiled_pixels(e, a, z, m, camera)
    if box is None:
        return out
    kernel = over_object(extent_su)
    pre, post = arrays.split_albedo(a, albedo_mode)
    light = e if pre is None else pre * e
    taps = kernel.offsets_su != 0
    surface = np.empty((0, 0), f32)
    if weighting == "surface":
        surface = np.empty(ok.shape, f32)  # the kernel writes each pixel's surface there, for its second pass
    backend.run_kernel(
        _kernels().ssss_kernel,
        c(light, dtype=f32),
        c(z),
        ok,
        cam,
        _follow(kernel, follow_surface),
        arrays.float32_factor(kernel.radius_su),
        c(kernel.offsets_su[taps], dtype=f32),
        c(kernel.weights[taps], dtype=f32),
        kernel.weights.sum(axis=0).astype(f32),
        c(post, dtype=f32),
        np.array(box, np.int64),
        surface_area_args(camera, ok.shape, 1.0 / MAX_SURFACE),
        surface,
        out,
    )
    return out


#: The tap counts offered: Unreal's low, medium and high quality (docs/references.md §3).
TAP_CHOICES = (
    (11, "11", "11 taps per direction (Unreal's low quality)"),
    (17, "17", "17 taps per direction (Unreal's medium quality)"),
    (25, "25", "25 taps per direction (Unreal's high quality)"),
)

#: SSSS's spec (``core/techniques/spec.py``): 17 taps, the signature's default, is Unreal's medium quality
#: (docs/references.md §3); the ladder is Unreal's low, medium and high.
TECHNIQUE = Technique(
    name="ssss",
    label="SSSS",
    description="Separable SSS: two 1-D per-channel convolutions",
    citation="docs/references.md §3; Jimenez et al. 2015, Separable Subsurface Scattering (Computer Graphics Forum)",
    function=ssss,
    scatters=True,
    adds_light=False,
    # The finite-object part of the energy (core/optics/energy.py) when the passes hold them.
    optional_passes=("Normal", "Position", THICKNESS),
    passes=("Combined", "Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Depth", "Material Index"),
    params=(
        Param(
            "n_taps",
            "Taps",
            "Samples of each of the two 1-D convolutions",
            type=int,
            choices=TAP_CHOICES,
        ),
        Param(
            "kernel_type",
            "Kernel",
            "How the separable kernel is built",
            type=str,
            choices=(
                ("preintegrated", "Pre-integrated", "Kernel integrated from the material's diffusion profile"),
                ("artist", "Artist", "Jimenez et al.'s artist-friendly kernel (strength and falloff per channel)"),
            ),
        ),
        Param(
            "weighting",
            "Tap Weight",
            "What each tap's weight stands for",
            type=str,
            choices=(
                (
                    "surface",
                    "Surface",
                    "The surface its pixel covers: a pixel seen at a grazing angle (a rim) covers more of the"
                    " surface and takes less of the lit interior's light",
                ),
                ("screen", "Screen", "The paper's: the screen area of its pixel, the same for every pixel"),
            ),
        ),
        ENERGY_PARAM,
    ),
    qualities=({"n_taps": 11}, {"n_taps": 17}, {"n_taps": 25}),
    default_quality=1,
    footprint=profile_footprint("n_taps"),
    calibration=CALIBRATE_MAPPING,
    fit=("gain", "d_scale"),
)
