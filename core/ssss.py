"""Separable subsurface scattering (SSSS): two 1-D per-channel convolutions, in NumPy.

Jimenez et al., "Separable Subsurface Scattering", Computer Graphics Forum 34(6), 2015, and
its reference code (iryoku/separable-sss), REFERENCES.md section 3. The diffuse light is
filtered horizontally, then vertically, with a kernel from ``core.kernels``; the taps are laid
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
"""

from __future__ import annotations

import numpy as np

from . import _arrays
from .kernels import SeparableKernel, check_taps, make_kernel
from .scene import Camera

ALBEDO_MODES = ("post", "pre-post")

#: Pixels (times taps) per block: small enough to stay in the cache, large enough to amortize calls.
_BLOCK_ELEMENTS = 1 << 16


def _pass(color, depth_key, scale, mask_idx, offsets, weights, fs_inv, axis):
    """One 1-D pass over the pixels ``mask_idx`` (flat indices) along ``axis`` (1 rows, 0 columns).

    ``depth_key`` is the depth of pixels that may give light and +inf elsewhere; ``scale`` is
    pixels per scene unit. Returns a copy of ``color`` with the masked pixels filtered.
    """
    h, w, _ = color.shape
    planes = [np.ascontiguousarray(color[..., c]).ravel() for c in range(3)]
    zflat = depth_key.ravel()
    sflat = scale.ravel()
    out = color.copy()
    oflat = out.reshape(-1, 3)
    n = offsets.size
    o = offsets.astype(np.float32)
    wt = weights.astype(np.float32)
    length, stride = (w, 1) if axis == 1 else (h, w)
    count = mask_idx.size
    block = max(256, _BLOCK_ELEMENTS // n)
    result = np.empty((count, 3), np.float32)

    def run(start, stop):
        idx = mask_idx[start:stop]
        coord = (idx % w) if axis == 1 else (idx // w)
        line = idx - coord * stride
        zc = zflat[idx][:, None]
        pos = coord[:, None].astype(np.float32) + sflat[idx][:, None] * o[None, :]
        np.clip(pos, 0.0, np.float32(length - 1), out=pos)
        fl = np.floor(pos)
        f = pos - fl  # float32: subtracting the integer array would promote everything to float64
        i0 = fl.astype(np.intp)
        i1 = np.minimum(i0 + 1, length - 1)
        j0 = line[:, None] + i0 * stride
        j1 = line[:, None] + i1 * stride
        z0 = zflat[j0]
        z1 = zflat[j1]
        with np.errstate(invalid="ignore"):
            if fs_inv > 0:
                g0 = np.minimum(np.abs(z0 - zc) * np.float32(fs_inv), 1.0)
                g1 = np.minimum(np.abs(z1 - zc) * np.float32(fs_inv), 1.0)
            else:
                g0 = np.isinf(z0).astype(np.float32)
                g1 = np.isinf(z1).astype(np.float32)
        a0 = (1.0 - f) * (1.0 - g0)
        a1 = f * (1.0 - g1)
        rest = 1.0 - a0 - a1
        for c in range(3):
            p = planes[c]
            t = a0 * p[j0] + a1 * p[j1]
            result[start:stop, c] = t @ wt[:, c] + (rest @ wt[:, c]) * p[idx]

    _arrays.for_blocks(count, block, run)
    oflat[mask_idx] = result
    return out


def filter_1d(image, *, offsets_px, weights, axis: int, mask=None) -> np.ndarray:
    """One 1-D pass with fixed pixel offsets (no depth, no follow-surface): the building block of
    the separable convolution, exposed for checks against a direct 2-D convolution.

    ``image`` (H, W, 3); ``offsets_px`` (n,); ``weights`` (n,) or (n, 3); ``axis`` 1 filters
    along rows (horizontally), 0 along columns. Taps outside the image or the mask give their
    weight to the centre pixel. Returns float32 (H, W, 3).
    """
    img = _arrays.image(image, "image")
    h, w, _ = img.shape
    o = np.asarray(offsets_px, dtype=np.float64)
    wt = np.asarray(weights, dtype=np.float64)
    if wt.ndim == 1:
        wt = np.repeat(wt[:, None], 3, axis=1)
    if o.ndim != 1 or wt.shape != (o.size, 3):
        raise ValueError(f"offsets_px/weights: expected (n,) and (n,) or (n, 3), got {o.shape} and {wt.shape}")
    if axis not in (0, 1):
        raise ValueError(f"axis: expected 0 (vertical) or 1 (horizontal), got {axis!r}")
    m = np.ones((h, w), bool) if mask is None else _arrays.mask_array(mask, (h, w))
    key = np.where(m, np.float32(0.0), np.float32(np.inf)).astype(np.float32)
    scale = np.ones((h, w), np.float32)
    return _pass(img, key, scale, np.flatnonzero(m), o, wt, 0.0, axis)


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
) -> np.ndarray:
    """Separable SSS of the diffuse light, with the albedo applied.

    ``diffuse`` (H, W, 3): diffuse light without the BSDF colour (Diffuse Direct + Indirect);
    ``albedo`` (H, W, 3): Diffuse Color; ``depth`` (H, W): planar view depth in scene units
    (1e10 background); ``mask`` (H, W) bool: the pixels that scatter; ``camera``: for the
    footprint in pixels. The kernel is ``kernel`` or built by ``core.kernels.make_kernel`` from
    ``kernel_type``, ``n_taps`` (odd: 11, 17, 25), ``d_su`` (the Burley d per channel, scene
    units) and the artist parameters. ``albedo_mode`` "post": A x filter(E); "pre-post":
    sqrt(A) x filter(sqrt(A) E).

    Returns float32 (H, W, 3): on the mask, the filtered light times the albedo; elsewhere,
    albedo x diffuse unchanged (NaN/Inf pixels keep their value and give no light).
    """
    if not isinstance(camera, Camera):
        raise ValueError(f"camera: expected a core.scene.Camera, got {type(camera).__name__}")
    if albedo_mode not in ALBEDO_MODES:
        raise ValueError(f"albedo_mode: {albedo_mode!r} is not one of {', '.join(ALBEDO_MODES)}")
    e = _arrays.image(diffuse, "diffuse")
    shape = e.shape[:2]
    a = _arrays.image(albedo, "albedo")
    z = _arrays.image(depth, "depth", None)
    _arrays.same_size(shape, albedo=a, depth=z)
    m = _arrays.mask_array(mask, shape)
    if kernel is None:
        check_taps(n_taps)
        if d_su is not None:
            _arrays.rgb_lengths(d_su, "d_su")
        kernel = make_kernel(kernel_type, n_taps, d_su=d_su, unit_su=unit_su, falloff=falloff, strength=strength)
    elif not isinstance(kernel, SeparableKernel):
        raise ValueError(f"kernel: expected a core.kernels.SeparableKernel, got {type(kernel).__name__}")

    base = a * e
    ok = m & _arrays.finite_pixels(e, a, z) & (z > 0) & (z < _arrays.BACKGROUND_DEPTH)
    if len(kernel) == 1 or not ok.any():
        return base
    scale = camera.pixels_per_unit(z)
    ok &= scale > 0
    # Pixels whose whole kernel is within one pixel would not change: skip them (EEVEE Next does).
    ok &= kernel.radius_su * scale > 0.5
    if not ok.any():
        return base
    if albedo_mode == "pre-post":
        root = np.sqrt(np.maximum(a, 0.0))
        light, post = root * e, root
    else:
        light, post = e, a
    light = np.where(ok[..., None], light, 0.0).astype(np.float32)
    key = np.where(ok, z, np.float32(np.inf)).astype(np.float32)
    fs_inv = 1.0 / (2.0 * kernel.radius_su) if follow_surface else 0.0
    idx = np.flatnonzero(ok)
    once = _pass(light, key, scale, idx, kernel.offsets_su, kernel.weights, fs_inv, axis=1)
    twice = _pass(once, key, scale, idx, kernel.offsets_su, kernel.weights, fs_inv, axis=0)
    out = base.copy()
    out[ok] = (post * twice)[ok]
    return out
