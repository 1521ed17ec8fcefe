"""Diffusion plus transmission: light entering through visible surfaces and light from behind.

SSSS and Burley redistribute the irradiance the camera sees; they add nothing for light that
enters on the far side of an object (docs/references.md §9). STA adds that light but colours it
with the albedo, where random walk filters it through the medium (thin green jade glows
saturated green, not pale). Real-time engines combine the two (HDRP's diffusion profile with
``ComputeTransmittanceDisney``, EEVEE Next likewise, docs/references.md §4 and §9):

    out = A x diffusion(E)                                      (Burley or SSSS, the visible light)
        + s_tr x W x sum_lights (E_L / pi) max(0, -N . L) x T_c(x)        (light from behind)

- ``diffusion`` is ``core.techniques.burley.technique.burley`` or ``core.techniques.ssss.technique.ssss`` with the
material's d per
  channel (docs/references.md §1); it conserves the visible diffuse light.
- The transmitted term follows what Cycles does for the material's subsurface method
  (docs/references.md §14): the irradiance the back of the object receives from each light
  (Lambert's cosine against the far surface's normal, ``far_side``: the visible normal reversed
  on a slab, the back seen through a round object for a walk; E_L as in ``core.optics.lights.light_at``:
  sun, point, spot and area lights), divided by pi (Cycles puts a diffuse closure at the walk's
  exit), times the per-channel transmittance T_c(x) through the slab thickness x read back from
  the baked map, x = D sqrt(1 - t) with D the bake distance (``core/scene/thickness.py``: a slab of
  thickness x bakes to AO (x / D)^2; where it finds no far side within D, the chord of the
  surface's curvature sphere), times the exit weight W at the visible surface.
  - Random walks (Random Walk, Skin, Legacy): T_c is the walk's own expectation through a slab
    (``core/optics/transmittance.py``: Cycles' extinction 1 / l_c and single-scattering albedo from Base
    Color, entry refracted from the view, 256 segments), and W = Diffuse Color / Base Color (the
    walk divides the closure weight by Base Color: the colour comes from the medium, not the albedo).
  - Christensen-Burley: its disk probes reach the far side and weigh each hit with the radial
    profile at the 3-D distance over the one at the disk radius; integrated over the far side
    that gives T_c(x) = int p(sqrt(rho^2 + x^2)) d rho (``core.optics.transmittance.disk_table``), more
    than the profile's own integral (e^{-x/d_c} + 3 e^{-x/(3 d_c)}) / 4; the closure keeps its
    weight: W = Diffuse Color.
  - Without a material (``subsurface_method`` None), Burley's T_c with W = 1.
  - Lateral spread (with ``depth`` and ``camera``): the light leaves the visible side up to about
    the thickness away from where it entered the far side. Each pixel gathers the transmitted
    light of its material and object with a Gaussian whose second moment is the walk's
    light-weighted squared lateral distance at its thickness (``core.optics.transmittance.lateral_spread``;
    Christensen-Burley: the profile's over the far side, ``spread_sigma``). The blur is
    interpolated between octave levels of width 1, 2, 4, ... 128 px (``spread_back_light``): the
    levels below ``SPREAD_COARSE_FROM_PX`` (16 px) at full resolution, three box filters per axis;
    the wider ones on a pyramid, the object's box summed in f x f blocks (f = width / 8, a power
    of two), blurred there at about 8 reduced pixels with the blocks' and the read back's own
    variance taken off, and read back bilinearly. So the cost per pixel does not grow with the
    widest width: at twice the resolution the widths double and the pyramid has one more
    level, of a sixty-fourth of the pixels (docs/references.md §14).
- No double counting: the diffusion redistributes the light that enters the visible surface (the
  Diffuse passes), the transmitted term the light that enters the far surface. On a slab the far
  normal is the visible one reversed: a light contributes to the transmitted term only where the
  visible surface faces away from it (N . L < 0), where it adds nothing to the Diffuse Direct
  pass, and the two terms meet at zero at the terminator. On a round object lit from the side both
  faces of a rim can take light from the same lamp: two entries, each counted once.

``transmission_scale`` s_tr (one number, or one per channel: the fit's tint of the transmitted
light) and ``transmission_d_su`` (the transmittance's length per channel: the walk's mean free
path, Christensen-Burley's d; the material's own by default) are what ``calibrate`` fits
against Cycles per material (``core/study/fit.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ...base import arrays
from ...compute import backend
from ...optics.lights import THICKNESS_CONVENTIONS, light_at, norm
from ...optics.medium import Medium, exit_weight, slab_transmittance_rgb
from ...optics.transmittance import (
    disk_spread,
    lateral_spread,
    legacy_single_scattering_albedo,
    single_scattering_albedo,
)
from ...scene.passes import THICKNESS
from ...scene.scene import Camera, Light
from ..burley import TECHNIQUE as BURLEY
from ..burley import burley
from ..spec import Footprint, Param, Technique, profile_footprint
from ..ssss import TECHNIQUE as SSSS
from ..ssss import ssss
from .pyramid import (
    SPREAD_LEVELS_PX,
    block_sums,
    blur,
    box_radius,
    box_sum,
    coarse_radii,
    full_levels,
    pyramid_layout,
    read_back,
    spread_factor,
    spread_levels,
)


def _spread_kernels():
    """The compiled kernels of the spread (``_spread_kernels.py``), loaded on first use."""
    return backend.kernels(__package__, "_spread_kernels")


if TYPE_CHECKING:
    from .back_light import CompiledBackLight

#: The diffusion part: Burley's spiral gather or the separable filter (faster at large kernels).
DIFFUSIONS = ("burley", "ssss")


def back_irradiance(*, normal, position, mask, lights) -> np.ndarray:
    """Irradiance from behind over pi, (H, W, 3) float32: sum over lights of light colour x
    E_L max(0, -N . L) / pi on ``mask``, 0 elsewhere and where an input is not finite.

    ``normal`` (H, W, 3) world-space normals of the visible surface; ``position`` (H, W, 3)
    world positions; ``lights``: ``core.scene.scene.Light`` entries (irradiance as
    ``core.techniques.sta.technique``)."""
    n = arrays.image(normal, "normal")
    shape = n.shape[:2]
    p = arrays.image(position, "position")
    arrays.same_size(shape, position=p)
    m = arrays.mask_array(mask, shape) & arrays.finite_pixels(n, p)
    out = np.zeros(shape + (3,), np.float32)
    idx = np.flatnonzero(m)
    if not idx.size:
        return out
    nr = n.reshape(-1, 3)[idx]
    pr = p.reshape(-1, 3)[idx]
    nx, ny, nz, _ = norm(nr[:, 0], nr[:, 1], nr[:, 2])
    acc = np.zeros((idx.size, 3), np.float32)
    for light in lights:
        if not isinstance(light, Light):
            raise ValueError(f"lights: expected core.scene.scene.Light entries, got {type(light).__name__}")
        if light.energy <= 0:
            continue
        lx, ly, lz, e = light_at(light, pr[:, 0], pr[:, 1], pr[:, 2])
        back = np.maximum(-(nx * lx + ny * ly + nz * lz), np.float32(0.0)) * e * np.float32(1.0 / math.pi)
        acc += back[:, None] * np.asarray(light.color, np.float32)[None, :]
    out.reshape(-1, 3)[idx] = acc
    return out


def far_side(*, translucency, distance_su, normal, position, mask, camera=None, medium=None):
    """(x, n) per pixel: the thickness x (scene units, float64 (H, W)) the light from behind
    crosses, and the normal n (float32 (H, W, 3)) whose reverse faces the surface it enters
    through, for ``back_irradiance`` (docs/references.md §14).

    x is ``slab_thickness`` of the map; where the map finds no far side within its distance D
    (translucency 0) the object is at least D thick, and x is the chord of the sphere of the
    surface's largest curvature, 2 / k, within D and ``core.optics.energy.CHORD_CAP`` D (as
    ``core.optics.energy.apply_energy`` reads the map). Without ``camera`` n is the visible normal.

    For a random walk (``medium`` walks) the far surface is the one the light enters through on
    its way towards the camera: on a slab the face behind the visible one (its normal the visible
    one reversed), on a round object the back seen through it, which faces away from the camera
    wherever the visible normal turns towards a rim. n blends the visible normal towards the
    direction of the camera v by how round the object is there, s = x k / 2 clipped to [0, 1]
    (0 on a slab, 1 on a sphere as thick as its curvature's: the shell measure of
    ``core.optics.energy.apply_energy``). Measured on the back-lit scenes (the irradiance the reference
    implies over the transmittance, per band of view cosine): flat or rising towards the rims,
    where the reversed visible normal falls by 2 to 10 times. Christensen-Burley's disk probes go
    along the visible normal's axis, and without a ``medium`` nothing is known: n stays the
    visible normal."""
    from ...optics.energy import CHORD_CAP, surface_curvature

    tau = np.clip(np.asarray(translucency, np.float64), 0.0, 1.0)
    x = float(distance_su) * np.sqrt(1.0 - tau)
    n = arrays.image(normal, "normal")
    if camera is None:
        return x, n
    p = arrays.image(position, "position")
    m = arrays.mask_array(mask, tau.shape) & arrays.finite_pixels(n, p)
    # Everything below on the mask's bounding box: it reads nothing outside it, and outside the
    # mask x stays the map's and n the visible normal.
    walks = medium is not None and medium.walks
    box = arrays.bounding_box(m)
    if box is None:
        return x, (n.astype(np.float32) if walks else n)
    mb, tb = m[box], tau[box]
    _, largest = surface_curvature(n[box], p[box], mb, radius_px=1)
    k = np.maximum(np.nan_to_num(np.asarray(largest, np.float64)), 0.0)
    chord = 2.0 / np.maximum(k, 2.0 / (CHORD_CAP * float(distance_su)))
    x[box] = np.where(mb & (tb <= 1e-6), np.maximum(x[box], chord), x[box])
    if not walks:
        return x, n
    s = np.clip(x[box] * k / 2.0, 0.0, 1.0)[..., None]
    nb = n[box]
    unit = nb / np.maximum(arrays.vector_length(nb), np.float32(1e-20))
    v = camera.view_vectors(p[box])
    blend = n.astype(np.float32)
    blend[box] = np.where(mb[..., None], (1.0 - s) * np.nan_to_num(unit) + s * v, nb)
    return x, blend


def view_cosine(normal, position, camera: Camera) -> np.ndarray:
    """|N . V| per pixel, float32 (H, W): the visible normal's cosine to the direction of the camera."""
    n = arrays.image(normal, "normal")
    nn = n / np.maximum(arrays.vector_length(n), np.float32(1e-20))
    v = camera.view_vectors(arrays.image(position, "position"))
    d = nn * v  # summed as np.sum along the last axis does, (x + y) + z, without its generic path
    return np.abs(np.nan_to_num(d[..., 0] + d[..., 1] + d[..., 2])).astype(np.float32)


def spread_sigma(x_su: np.ndarray, length_su, medium: Medium | None) -> np.ndarray:
    """Per-axis standard deviation (scene units, (..., 3)) of the Gaussian whose second moment is the
    light-weighted mean squared lateral distance between where light enters the far side and
    where it leaves the visible one, through thickness ``x_su``: the random walk's
    (``core.optics.transmittance.lateral_spread``, entering along the normal), or for Burley's law the
    profile's over the far side, E[rho^2] = sum_a a e^{-x/a} (2 a x + 2 a^2) / sum_a a e^{-x/a}
    with a in (d, 3 d) (rho^2 = r^2 - x^2 against R(r) 2 pi r dr). E[r^2] = 2 sigma^2."""
    x = np.asarray(x_su, np.float64)
    lengths = arrays.rgb_lengths(length_su, "transmission_d_su").astype(np.float64)
    out = np.zeros(x.shape + (3,), np.float32)
    if medium is not None and medium.walks:
        alpha = single_scattering_albedo(medium.base_color, medium.anisotropy)
        if medium.method == "RANDOM_WALK_LEGACY" and medium.anisotropy >= 0:
            alpha = legacy_single_scattering_albedo(medium.base_color, medium.anisotropy)
        for c in range(3):
            if lengths[c] > 0:
                rms = lateral_spread(x / lengths[c], alpha[c]) * lengths[c]
                out[..., c] = np.nan_to_num(rms, nan=float(np.nanmax(rms, initial=0.0))) / math.sqrt(2.0)
        return out
    if medium is not None:  # Christensen-Burley: the disk probes' weight over the far side
        for c in range(3):
            out[..., c] = disk_spread(x, lengths[c]) / math.sqrt(2.0)
        return out
    for c in range(3):
        d = lengths[c]
        if d <= 0:
            continue
        num = sum(a * np.exp(-x / a) * (2 * a * x + 2 * a * a) for a in (d, 3 * d))
        den = sum(a * np.exp(-x / a) for a in (d, 3 * d))
        out[..., c] = np.sqrt(num / np.maximum(den, 1e-300) / 2.0)
    return out


def spread_back_light(e: np.ndarray, mask: np.ndarray, sigma_px: np.ndarray) -> np.ndarray:
    """``e`` (H, W, 3) on ``mask`` blurred per pixel and channel by a Gaussian of ``sigma_px``
    (H, W, 3) px, renormalized over the mask (light from outside it is not gathered; the
    normalization keeps a uniform light unchanged): interpolated between blurs at
    ``SPREAD_LEVELS_PX``. Pixels with sigma below the first level keep a share of their own value.
    Levels of width ``SPREAD_COARSE_FROM_PX`` and more are blurred on reduced grids (a pyramid:
    block sums of the light on the mask and of the mask, ``block_sums``; boxes of
    ``coarse_radii``; bilinear read back, ``read_back``), each a quarter of the one below it.
    Against the same levels at full resolution: max 2.8 %, RMS 0.4-0.6 % relative difference for
    widths 2-40 px (``tests/core/test_combined.py``), less than those levels themselves miss a
    direct Gaussian by (3.6-5.4 % / 1.2-1.3 %).

    On the compiled backend ``core.techniques.combined._spread_kernels.spread_light`` computes it with the same
    float32 and
    float64 operations in the same order (equal to the bit: check mode compares with bound 0); the
    NumPy code below is the reference (``core.compute.backend``)."""
    mode = backend.active()
    if mode == "numpy":
        return _spread_reference(e, mask, sigma_px)
    result = _spread_compiled(e, mask, sigma_px)
    if mode == "check":
        reference = _spread_reference(e, mask, sigma_px)
        backend.compare("spread_back_light", reference, result, np.zeros(reference.shape))
    return result


def _spread_compiled(e: np.ndarray, mask: np.ndarray, sigma_px: np.ndarray) -> np.ndarray:
    """``spread_back_light`` on the compiled backend (``core.techniques.combined._spread_kernels.spread_light`` for
    the levels
    at full resolution, ``_reduced_levels`` and ``spread_reduced_frame`` for the wider ones)."""
    top = float(np.max(sigma_px[mask], initial=0.0))
    sigmas = spread_levels(top)
    if len(sigmas) == 1:
        return e
    c = np.ascontiguousarray
    e32 = c(e, np.float32)
    m = c(mask, bool)
    sig = c(sigma_px, np.float32)
    out = np.empty(e32.shape, np.float32)
    prev = np.empty((3,) + m.shape, np.float32)
    radii = np.array([box_radius(sg) for sg in sigmas[1:]], np.int64)
    grid = np.asarray(sigmas, np.float64)
    n_full = full_levels(sigmas)
    backend.run_kernel(_spread_kernels().spread_light, e32, m, sig, grid, n_full, radii, prev, out)
    whole = np.array([0, m.shape[0], 0, m.shape[1]], np.int64)
    levels, size = pyramid_layout(sigmas, whole, None)
    flat = np.empty(size, np.float32)
    for k, f, reduced in _reduced_levels(e32, m.view(np.uint8), whole, whole, sigmas, levels, flat):
        backend.run_kernel(_spread_kernels().spread_reduced_frame, m, sig, f, reduced, grid, k, prev, out)
    return out


def _reduced_levels(light, on, part, box, sigmas, levels, flat):
    """The compiled pyramid (``_spread_reference``'s reduced levels): yields (k, f, the level's
    blurred reduced grid (4, rows, columns) float32: R, G, B and the mask) for each level k of
    ``sigmas`` blurred on blocks of f x f of ``box``, in ``flat`` as ``levels`` lays them out
    (``pyramid_layout``; a level with f = 0 is not made). ``core.techniques.combined._spread_kernels.spread_pyramid``
    makes the float32 of their block sums from the light ``light`` on the pixels ``on`` of
    ``part`` (region coordinates), ``blur_reduced`` blurs each."""
    n_full = full_levels(sigmas)
    if not np.any(levels[:, 0] > 0):
        return
    backend.run_kernel(
        _spread_kernels().spread_pyramid,
        light,
        on,
        part,
        box,
        levels,
        flat,
        0,
        1 << 62,
        0,
        part[0],
    )
    for k in range(n_full, len(sigmas)):
        f, off, hc, wc = (int(v) for v in levels[k - n_full])
        if f == 0:
            continue
        reduced = flat[off : off + 4 * hc * wc].reshape(4, hc, wc)
        radii = np.array(coarse_radii(sigmas[k], f), np.int64)
        backend.run_kernel(_spread_kernels().blur_reduced, radii, reduced)
        yield k, f, reduced


def _spread_reference(e: np.ndarray, mask: np.ndarray, sigma_px: np.ndarray) -> np.ndarray:
    """``spread_back_light`` in NumPy: the reference."""
    m = mask.astype(np.float32)
    top = float(np.max(sigma_px[mask], initial=0.0))
    levels = [e]
    sigmas = [0.0]
    sums = None  # the reduced grid's float64 block sums (light on the mask, the mask) at factor f
    f = 1
    for sg in SPREAD_LEVELS_PX:
        if sigmas[-1] >= top:
            break
        lit = e * m[..., None]
        if spread_factor(sg) == 1:
            num = blur(lit, sg)
            den = blur(m, sg)
        else:
            # The pyramid: halve the grid until the blocks are f x f, blur there, read back.
            if sums is None:
                sums = np.concatenate([lit, m[..., None]], axis=2)
            while f < spread_factor(sg):
                sums = block_sums(sums)
                f *= 2
            reduced = sums.astype(np.float32)
            for axis in (0, 1):
                for r in coarse_radii(sg, f):
                    reduced = box_sum(reduced, r, axis)
            both = read_back(reduced, f, *m.shape)
            num = both[..., :3].astype(np.float32)
            den = both[..., 3].astype(np.float32)
        levels.append(num / np.maximum(den, np.float32(1e-6))[..., None])
        sigmas.append(sg)
    if len(levels) == 1:
        return e
    grid = np.asarray(sigmas)
    s = np.clip(sigma_px, 0.0, grid[-1])
    hi = np.clip(np.searchsorted(grid, s, side="left"), 1, len(grid) - 1)
    lo = hi - 1
    w = ((s - grid[lo]) / (grid[hi] - grid[lo])).astype(np.float32)
    stack = np.stack(levels)  # (L, H, W, 3)
    yy, xx, cc = np.indices(e.shape)
    out = (1.0 - w) * stack[lo, yy, xx, cc] + w * stack[hi, yy, xx, cc]
    return np.where(mask[..., None], out, e).astype(np.float32)


def _spread_part(out: np.ndarray, part: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """``spread_back_light`` of ``out`` over the pixels ``part`` (sigma (k, 3) px, one row per
    pixel of ``part``), computed on ``part``'s bounding box widened by the widest blur's reach
    (the same values as on the whole frame: nothing outside the box takes part)."""
    ys, xs = np.nonzero(part)
    if ys.size == 0:
        return out
    # The level used is at most twice the widest sigma; three boxes of half-width ~sigma reach 3 sigma.
    pad = int(math.ceil(6.0 * float(sigma.max(initial=0.0)))) + 3
    h, w = part.shape
    box = (
        slice(max(ys.min() - pad, 0), min(ys.max() + pad + 1, h)),
        slice(max(xs.min() - pad, 0), min(xs.max() + pad + 1, w)),
    )
    sub = part[box]
    sig = np.zeros(sub.shape + (3,), np.float32)
    sig[sub] = sigma
    spread = spread_back_light(out[box], sub, sig)
    out = out.copy()
    out[box] = np.where(sub[..., None], spread, out[box])
    return out


def transmission(*, d_su, transmission_scale=1.0, **inputs) -> np.ndarray:
    """The light from behind alone, float32 (H, W, 3): ``transmission_scale`` x ``exit_weight`` x
    ``back_irradiance`` x T_c(x), with x = ``slab_thickness`` of the map (scene units) and T_c
    from ``slab_transmittance_rgb`` (``d_su`` its length per channel: the walk's mean free path,
    or Burley's d without a ``medium``). ``inputs``: ``back_light``'s arguments, the part that
    does not depend on the length."""
    arrays.rgb_lengths(transmission_scale, "transmission_scale")
    arrays.rgb_lengths(d_su, "transmission_d_su")
    return back_light(**inputs).transmitted(d_su, transmission_scale)


@dataclass
class BackLight:
    """What ``transmission`` reads that does not depend on the transmittance's length: the slab
    thickness x (H, W) and the irradiance over pi (H, W, 3) of the far side, the pixels it lights,
    the view cosine of the walk's entry, the parts the light spreads within with their pixels per
    scene unit, and the exit weight. ``transmitted`` gives the light at a length; a caller that
    tries many lengths (``core/study/fit.py``) builds this once."""

    x: np.ndarray
    irradiance: np.ndarray
    lit: np.ndarray
    medium: Medium | None
    view_cos: np.ndarray | None
    parts: list
    ppu: np.ndarray | None
    weight: np.ndarray | None

    def transmitted(self, d_su, transmission_scale=1.0) -> np.ndarray:
        """``transmission`` at the length ``d_su`` (R, G, B) and the scale ``transmission_scale``."""
        scale = arrays.rgb_lengths(transmission_scale, "transmission_scale").astype(np.float32)
        e, lit = self.irradiance, self.lit
        out = np.zeros_like(e)
        if lit.any():
            x = self.x[lit]
            view = None if self.view_cos is None else self.view_cos[lit]
            out[lit] = e[lit] * slab_transmittance_rgb(x, d_su, self.medium, view_cos=view)
        for part in self.parts:
            assert self.ppu is not None  # parts are found only with a depth pass, which gives ppu
            out = _spread_part(out, part, spread_sigma(self.x[part], d_su, self.medium) * self.ppu[part][:, None])
        if self.weight is not None:
            out *= self.weight
        if np.any(scale != 1):
            out *= scale
        return out

    def add_to(self, out: np.ndarray, d_su, transmission_scale=1.0, *, last: bool = False) -> None:
        """``out`` += ``transmitted(d_su, transmission_scale)`` (``out`` float32 (H, W, 3)).
        ``last``: no call follows (the compiled backend may then reuse what it holds)."""
        out += self.transmitted(d_su, transmission_scale)


def back_light(
    *,
    normal,
    position,
    thickness,
    mask,
    lights,
    thickness_distance_su: float,
    thickness_convention: str = "translucency",
    medium: Medium | None = None,
    albedo=None,
    camera: Camera | None = None,
    albedo_mode: str = "post",
    depth=None,
    object_id=None,
) -> BackLight | CompiledBackLight:
    """The length-independent part of ``transmission`` (on the compiled backend, with a medium,
    ``core.techniques.combined.back_light.CompiledBackLight``: the same ``transmitted`` and ``add_to``).

    ``thickness`` (H, W) baked map in ``thickness_convention`` ("translucency": 1 = thin);
    ``thickness_distance_su`` the bake's distance D (> 0: without it the map cannot be read as a
    thickness). ``albedo`` (the Diffuse Color pass) and ``camera`` (for the view cosine of the
    walk's refracted entry) are optional: without them the exit weight is 1 and the entry normal.
    ``depth`` (the Depth pass, with ``camera``) turns on the lateral spread, ``object_id`` keeps it
    within each object."""
    if thickness_convention not in THICKNESS_CONVENTIONS:
        raise ValueError(
            f"thickness_convention: {thickness_convention!r} is not one of {', '.join(THICKNESS_CONVENTIONS)}"
        )
    distance = arrays.positive_finite(thickness_distance_su, "thickness_distance_su", allow_zero=False)
    t = arrays.image(thickness, "thickness", None)
    arguments = dict(
        normal=normal, position=position, thickness=thickness, mask=mask, lights=lights,
        thickness_distance_su=thickness_distance_su, thickness_convention=thickness_convention, medium=medium,
        albedo=albedo, camera=camera, albedo_mode=albedo_mode, depth=depth, object_id=object_id,
    )  # fmt: skip
    mode = backend.active()
    if mode != "numpy" and medium is not None:
        from .back_light import compiled_back_light

        compiled = compiled_back_light(t, distance, **arguments)
        if compiled is not None:
            if mode == "check":
                with backend.use("numpy"):
                    compiled.reference = back_light(**arguments)
            return compiled
    ok = np.isfinite(t)
    tt = np.where(ok, t, np.float32(0.0))
    if thickness_convention == "thickness":
        tt = np.float32(1.0) - tt
    x_all, far_normal = far_side(
        translucency=tt, distance_su=distance, normal=normal, position=position, mask=mask, camera=camera, medium=medium
    )
    e = back_irradiance(normal=far_normal, position=position, mask=mask, lights=lights)
    arrays.same_size(e.shape[:2], thickness=t)
    lit = (e.max(axis=2) > 0) & ok
    view_cos = None
    if camera is not None and medium is not None and medium.walks:
        # Read on the lit pixels only: computed on their bounding box (0 elsewhere).
        view_cos = np.zeros(lit.shape, np.float32)
        box = arrays.bounding_box(lit)
        if box is not None:
            view_cos[box] = view_cosine(
                arrays.image(normal, "normal")[box], arrays.image(position, "position")[box], camera
            )
    parts, ppu = [], None
    if depth is not None and camera is not None and lit.any():  # no light from behind: nothing to spread
        # The light a walk leaves with entered the far side up to about the thickness away.
        m = arrays.mask_array(mask, e.shape[:2]) & ok
        ppu = camera.pixels_per_unit(arrays.image(depth, "depth", None))
        if object_id is None:
            parts = [m]
        else:  # light does not cross from one object to another
            ids = np.asarray(object_id)
            ids = ids[..., 0] if ids.ndim == 3 else ids
            parts = [m & (ids == i) for i in np.unique(ids[m])]
    w = exit_weight(albedo, medium, albedo_mode)
    if w is not None:
        arrays.same_size(e.shape[:2], albedo=w)
    return BackLight(x_all, e, lit, medium, view_cos, parts, ppu, w)


def combined(
    *,
    diffuse,
    albedo,
    depth,
    mask,
    camera: Camera,
    d_su,
    normal,
    position,
    thickness,
    lights,
    thickness_distance_su: float,
    object_id=None,
    diffusion: str = "burley",
    n_samples: int = 32,
    n_taps: int = 17,
    adaptive: bool = True,
    random_rotation: bool = True,
    seed: int = 0,
    smooth_px: int = 1,
    transmission_scale=1.0,
    transmission_d_su=None,
    gain=(1.0, 1.0, 1.0),
    thickness_convention: str = "translucency",
    albedo_mode: str = "post",
    mfp_su=None,
    subsurface_method: str | None = None,
    base_color=(0.8, 0.8, 0.8),
    subsurface_ior: float = 1.4,
    subsurface_anisotropy: float = 0.0,
    energy: str = "object",
    plan_d_su=None,
) -> np.ndarray:
    """Diffusion of the visible light plus transmission of the light from behind, float32 (H, W, 3).

    Inputs as ``core.techniques.burley.technique.burley`` (``diffuse``, ``albedo``, ``depth``, ``mask``, ``camera``,
    ``d_su``, ``object_id``) and ``transmission`` (``normal``, ``position``, ``thickness``,
    ``lights``, ``thickness_distance_su``, ``thickness_convention``). ``diffusion`` "burley"
    (``n_samples``, ``adaptive``, ``random_rotation``, ``seed``, ``smooth_px``, Burley's defaults) or "ssss"
    (``n_taps``, pre-integrated kernel). ``transmission_d_su`` None uses ``mfp_su``
    (the method's length, ``core.pipeline.mapping.mean_free_path``), or ``d_su`` without it;
    ``subsurface_method``, ``base_color``, ``subsurface_ior``, ``subsurface_anisotropy``: the
    material's medium for the light from behind (module docstring), None for Burley's law.
    ``gain`` (R, G, B) multiplies the diffusion's light on the mask (the fitted energy,
    ``core/pipeline/fit_params.py``), not the transmitted light, whose level is ``transmission_scale``.
    Returns, like Burley and SSSS, the albedo-applied scattered light on the mask (plus the
    transmitted light) and albedo x diffuse elsewhere. Formula, sources and why nothing is
    counted twice: the module docstring. ``energy``: the diffusion's entry energy, as
    Burley's (``core.optics.energy``). ``plan_d_su``: Burley's (the d its adaptive plan reads, a
    fitted material's own; None: ``d_su``).
    """
    if diffusion not in DIFFUSIONS:
        raise ValueError(f"diffusion: {diffusion!r} is not one of {', '.join(DIFFUSIONS)}")
    d = arrays.rgb_lengths(d_su, "d_su")
    medium, d_tr = _medium_and_length(locals())
    # The diffusion's energy (core/optics/energy.py); the transmission below carries the lamps' light
    # from behind, so the diffusion's unseen-side light leaves them out.
    energy_kw = {
        "energy": energy,
        "subsurface_method": subsurface_method,
        "normal": normal,
        "position": position,
        "thickness": thickness,
        "lights": lights,
        "mfp_su": mfp_su,
        "thickness_distance_su": thickness_distance_su,
        "thickness_convention": thickness_convention,
        "lamps_behind": False,
    }
    if diffusion == "burley":
        out = burley(
            diffuse=diffuse,
            albedo=albedo,
            depth=depth,
            mask=mask,
            camera=camera,
            d_su=tuple(d),
            object_id=object_id,
            n_samples=n_samples,
            adaptive=adaptive,
            random_rotation=random_rotation,
            seed=seed,
            smooth_px=smooth_px,
            albedo_mode=albedo_mode,
            plan_d_su=plan_d_su,
            **energy_kw,
        )
    else:
        out = ssss(
            diffuse=diffuse,
            albedo=albedo,
            depth=depth,
            mask=mask,
            camera=camera,
            n_taps=n_taps,
            d_su=tuple(d),
            albedo_mode=albedo_mode,
            **energy_kw,
        )
    g = arrays.rgb_lengths(gain, "gain").astype(np.float32)
    m = arrays.mask_array(mask, out.shape[:2])
    if np.any(g != 1):
        out[m] *= g
    scale = arrays.rgb_lengths(transmission_scale, "transmission_scale")
    if scale.max() > 0:
        back_light(**_back_light_arguments(locals(), medium)).add_to(out, tuple(d_tr), tuple(scale), last=True)
    return out


def _medium_and_length(arguments: dict) -> tuple[Medium | None, np.ndarray]:
    """The light from behind's medium and length per channel from ``combined``'s arguments: the
    material's walk (None without a method: Burley's law) and ``transmission_d_su``, else
    ``mfp_su``, else ``d_su``."""
    a = arguments
    medium = None
    if a["subsurface_method"] is not None:
        color, ior, anisotropy = tuple(a["base_color"]), float(a["subsurface_ior"]), float(a["subsurface_anisotropy"])
        medium = Medium(a["subsurface_method"], color, ior, anisotropy)
    if a["transmission_d_su"] is not None:
        return medium, arrays.rgb_lengths(a["transmission_d_su"], "transmission_d_su")
    if a["mfp_su"] is not None:
        return medium, arrays.rgb_lengths(a["mfp_su"], "mfp_su")
    return medium, arrays.rgb_lengths(a["d_su"], "d_su")


def _back_light_arguments(arguments: dict, medium: Medium | None) -> dict:
    """``back_light``'s arguments from ``combined``'s."""
    a = arguments
    keys = ("normal", "position", "thickness", "lights", "thickness_distance_su", "thickness_convention")
    return {
        **{k: a[k] for k in keys},
        "mask": arrays.mask_array(a["mask"], arrays.image(a["diffuse"], "diffuse").shape[:2]),
        "medium": medium,
        "albedo": a["albedo"] if medium is not None else None,
        "camera": a["camera"],
        "albedo_mode": a["albedo_mode"],
        "depth": a["depth"],
        "object_id": a["object_id"],
    }


def light_from_behind(arguments: dict) -> tuple[BackLight | CompiledBackLight, np.ndarray]:
    """What ``combined`` called with ``arguments`` (all its keyword arguments, defaults included)
    adds as light from behind, before its length, and that length per channel: ``combined`` adds
    ``back.transmitted(length x its fitted factors, transmission_scale)``. ``core/study/fit.py`` tries
    many lengths on one ``BackLight``."""
    medium, length = _medium_and_length(arguments)
    return back_light(**_back_light_arguments(arguments, medium)), length


def _prepare(params: dict) -> list[str]:
    """Without the bake's distance the map cannot be read as a thickness: diffusion only."""
    if params.get("thickness_distance_su"):
        return []
    params["transmission_scale"] = 0.0
    return [
        "no light from behind: the material's thickness map has no bake distance (bake it with"
        " SSS Lab's Bake Thickness); diffusion only"
    ]


#: The parameter that counts the samples of each diffusion.
_SAMPLES = {"burley": "n_samples", "ssss": "n_taps"}


def _footprint(params) -> Footprint:
    """16 d like Burley and SSSS, with the samples of the diffusion in use."""
    return profile_footprint(_SAMPLES[params.get("diffusion", "burley")])(params)


def _own(p: Param) -> Param:
    """Another technique's parameter spec, with this function's default (filled in from the signature)."""
    return replace(p, default=None)


#: The combined technique's spec (``core/techniques/spec.py``): Burley's diffusion at its default samples; the
#: transmission's d is the diffusion's unless fitted.
TECHNIQUE = Technique(
    name="combined",
    label="Combined",
    description="Burley diffusion of the visible light plus the light from behind carried through the baked"
    " thickness as Cycles' subsurface method carries it",
    citation="docs/references.md §1, §4, §9 and §14; Christensen & Burley 2015 (profile and transmittance)",
    function=combined,
    scatters=True,
    adds_light=True,
    # Burley's passes, and STA's for the light from behind.
    passes=(*BURLEY.passes, "Normal", "Position", THICKNESS),
    params=(
        Param(
            "diffusion",
            "Diffusion",
            "How the visible light is scattered",
            type=str,
            choices=(
                ("burley", "Burley", "Burley's golden-angle spiral (Samples)"),
                ("ssss", "SSSS", "The separable filter, faster at large kernels (Taps)"),
            ),
        ),
        # The diffusions' own parameters, as Burley and SSSS declare them (defaults: this signature).
        _own(BURLEY.param("n_samples")),
        _own(SSSS.param("n_taps")),
        _own(BURLEY.param("random_rotation")),
        _own(BURLEY.param("adaptive")),
        _own(BURLEY.param("energy")),
        Param(
            "transmission_scale",
            "Light from Behind",
            "Scale of the light transmitted from behind (1: as the Burley transmittance gives it)",
            min=0.0,
            soft_max=4.0,
        ),
    ),
    qualities=({"diffusion": "ssss", "n_taps": 11}, {"n_samples": 16}, {"n_samples": 32}),
    default_quality=2,
    footprint=_footprint,
    # Its diffusion alone, for the fidelity table: no light from behind on the lit line.
    diffusion_only={"transmission_scale": 0.0, "normal": None, "position": None, "thickness": None, "lights": ()},
    prepare=_prepare,
    fit=("gain", "d_scale", "transmission_scale", "transmission_d_su"),
)
