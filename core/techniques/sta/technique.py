"""Simple translucency approximation (STA), in NumPy.

Barre-Brisebois & Bouchard, "Approximating Translucency for a Fast, Cheap and Convincing
Subsurface Scattering Look", GDC 2011 / GPU Pro 2 (docs/references.md §4). Per light:

    L_T   = normalize(L + d_T N)                 (the seed deck and three.js normalize it)
    T_dir = s_T max(0, V . -L_T)^p_T
    T     = A_L t (T_dir + a_T)
    added = albedo x light colour x (E_L / pi) x T

L points from the surface to the light, V from the surface to the viewer, N is the shading
normal, t the local thickness map in the translucency convention (1 = thin; a map in the
thickness convention is read as 1 - t). A_L is the light's attenuation and E_L its irradiance
at the point in Blender's units: a sun gives its Strength (W/m^2); a point or spot light of
power P at distance r gives P / (4 pi r^2), a spot times Cycles' smoothstep cone falloff
(spot_size, spot_blend); an area light of power P gives P cos(theta_L) / (pi r^2). The 1 / pi
is a Lambertian surface's, so that s_T = 1 makes the translucency as bright as a diffuse surface
facing the light; the original leaves the scale to the artist.

Extremes, each tested: when L + d_T N vanishes the direction is undefined and that light adds
nothing there; p_T = 0 gives s_T wherever V . -L_T > 0 (and nothing where it is <= 0); large p_T
(e.g. 128) narrows the lobe without overflow; thickness 0 adds nothing, 1 the full term.
"""

from __future__ import annotations

import functools
import inspect
import math

import numpy as np

from ... import optics
from ...base import arrays
from ...compute import backend
from ...optics.lights import THICKNESS_CONVENTIONS, light_at, norm
from ...optics.medium import Medium, slab_transmittance_rgb
from ...scene.passes import THICKNESS
from ...scene.scene import Camera, Light
from ..spec import Param, Technique


def _kernels():
    """This package's compiled kernels (``_kernels.py``), loaded on first use."""
    return backend.kernels(__package__)


def _optics_kernels():
    """The shared physics' compiled kernels (``core/optics/_kernels.py``), loaded on first use."""
    return backend.kernels(optics.__name__)


_EPS = np.float32(1e-6)

FALLOFFS = ("medium", "map", "burley")


def _transmittance(translucency: np.ndarray, distance: float, d_c: np.ndarray) -> np.ndarray:
    """Per-channel Burley transmittance (B, 3) through the slab thickness the map stands for."""
    f32 = np.float32
    x = f32(distance) * np.sqrt(np.maximum(f32(1.0) - translucency, f32(0.0)))
    out = np.empty((x.size, 3), f32)
    for c in range(3):
        if d_c[c] > 0:
            e3 = np.exp(-x / f32(3.0 * d_c[c]))
            out[:, c] = f32(0.25) * (e3 * e3 * e3 + f32(3.0) * e3)
        else:  # no scattering distance: only a part of zero thickness lets light through
            out[:, c] = (x == 0).astype(f32)
    return out


#: Pixels per block: the planar rows of a block stay in the cache.
_BLOCK = 1 << 16


def _check_bound(args: dict, reference: np.ndarray) -> np.ndarray:
    """Check mode's bound (``backend.checked``): per pixel, a sum over the lights of non-negative
    terms (the result itself is their size)."""
    return backend.tolerance(len(args["lights"]), reference)


@backend.checked(bound=_check_bound)
def sta(
    *,
    albedo,
    normal,
    position,
    thickness,
    mask,
    camera: Camera,
    lights,
    distortion: float = 0.1,
    power: float = 2.0,
    scale: float = 1.0,
    ambient: float = 0.0,
    thickness_convention: str = "translucency",
    falloff: str = "medium",
    d_su=None,
    thickness_distance_su: float = 0.0,
    mfp_su=None,
    subsurface_method: str | None = None,
    base_color=(0.8, 0.8, 0.8),
    subsurface_ior: float = 1.4,
    subsurface_anisotropy: float = 0.0,
) -> np.ndarray:
    """The translucency term STA adds, float32 (H, W, 3); zero outside ``mask``.

    ``falloff`` "medium" (the default): the map is read back as a slab thickness x (below) and the
    term is filtered through the material's medium as Cycles' subsurface method carries light
    through a slab (``core.optics.medium.slab_transmittance_rgb``, docs/references.md §14: the random
    walk's per-channel transmittance for the walks, the disk probes' for Christensen-Burley,
    Burley's law with ``d_su`` without ``subsurface_method``), and the albedo is replaced by the
    exit weight Cycles puts on that light (``core.optics.medium.exit_weight``: Diffuse Color / Base
    Color for a walk, whose medium does the colouring; Diffuse Color for Christensen-Burley).
    ``mfp_su`` (the method's mean free path per channel, ``core.pipeline.mapping.mean_free_path``; ``d_su``
    without it), ``subsurface_method``, ``base_color``, ``subsurface_ior`` and
    ``subsurface_anisotropy`` describe the medium. STA's view lobe, scale and ambient stay as in
    the paper. "map" (the paper's): the term is scaled by the translucency map t itself, the
    same for R, G and B, and coloured by the albedo. "burley": the map is read back as a slab thickness,
    x = D sqrt(1 - t) (the bake's AO of a slab is (x / D)^2, ``core/scene/thickness.py``, with D =
    ``thickness_distance_su``), and each channel is scaled by the Burley transmittance
    T_c(x) = (e^{-x/d_c} + 3 e^{-x/3d_c}) / 4 for the profile shape ``d_su`` (HDRP's
    ComputeTransmittanceDisney, docs/references.md §4; the albedo is applied as before): thin
    parts pass every channel, thicker ones mostly the channel that scatters furthest.

    ``albedo`` (H, W, 3) Diffuse Color; ``normal`` (H, W, 3) world-space normals; ``position``
    (H, W, 3) world positions; ``thickness`` (H, W) in [0, 1]; ``lights``: core.scene.scene.Light list.
    ``distortion`` d_T, ``power`` p_T, ``scale`` s_T, ``ambient`` a_T as in the paper.
    STA adds light (it models light arriving from behind, not redistributed light): its sum is
    not conserved, by design. Pixels with non-finite inputs get 0.
    """
    settings = _settings(
        camera, lights, distortion, power, scale, ambient, thickness_convention, falloff, d_su,
        thickness_distance_su, mfp_su, (subsurface_method, base_color, subsurface_ior, subsurface_anisotropy),
    )  # fmt: skip
    distortion, power, scale, ambient, d_c, distance, through = settings
    a = arrays.image(albedo, "albedo")
    shape = a.shape[:2]
    n = arrays.image(normal, "normal")
    p = arrays.image(position, "position")
    t = arrays.image(thickness, "thickness", None)
    arrays.same_size(shape, normal=n, position=p, thickness=t)
    m = arrays.mask_array(mask, shape)
    lights = [light for light in lights if light.energy > 0]
    if not m.any() or not lights:
        return np.zeros(a.shape, np.float32)
    args = (a, n, p, t, m, camera, lights, distortion, power, scale, ambient, thickness_convention)
    if backend.active() == "numba":
        out = np.empty(a.shape, np.float32)  # the kernel writes every pixel (zeros off the mask)
        _compiled(*args, out, d_c, distance, through)
        return out
    return _reference(*args, d_c, distance, through)


def _settings(
    camera, lights, distortion, power, scale, ambient, convention, falloff, d_su, distance_su, mfp_su, medium_args
):
    """``sta``'s parameters checked (ValueError naming the one that is not valid) and as its code
    takes them: (distortion, power, scale, ambient, the "burley" falloff's lengths per channel or
    None, its bake distance or 0, the "medium" falloff's ``_medium_inputs`` or None)."""
    distortion = _checked(camera, convention, lights, distortion, falloff)
    # Per-channel Burley transmittance through the slab the map stands for, or the paper's map.
    d_c, distance = None, 0.0
    if falloff == "burley":
        d_c = arrays.rgb_lengths(d_su, "d_su")
        distance = arrays.positive_finite(distance_su, "thickness_distance_su", allow_zero=False)
    # Through the medium: the transmittance tabulated over thickness and view cosine, and the
    # exit weight's per-channel factor (1 / Base Color, clipped to 1, for a walk).
    through = None
    if falloff == "medium":
        through = _medium_inputs(d_su if mfp_su is None else mfp_su, distance_su, medium_args)
    power = arrays.positive_finite(power, "power")
    scale = arrays.positive_finite(scale, "scale")
    ambient = arrays.positive_finite(ambient, "ambient")
    return distortion, power, scale, ambient, d_c, distance, through


def _checked(camera, thickness_convention, lights, distortion, falloff) -> float:
    """``sta``'s checks of its camera, convention, lights and falloff; the distortion as a float."""
    if not isinstance(camera, Camera):
        raise ValueError(f"camera: expected a core.scene.scene.Camera, got {type(camera).__name__}")
    if thickness_convention not in THICKNESS_CONVENTIONS:
        raise ValueError(
            f"thickness_convention: {thickness_convention!r} is not one of {', '.join(THICKNESS_CONVENTIONS)}"
        )
    for light in lights:
        if not isinstance(light, Light):
            raise ValueError(f"lights: expected core.scene.scene.Light entries, got {type(light).__name__}")
    try:
        distortion = float(distortion)
    except (TypeError, ValueError):
        raise ValueError(f"distortion: expected a number, got {distortion!r}") from None
    if not math.isfinite(distortion):
        raise ValueError(f"distortion: expected a finite number, got {distortion!r}")
    if falloff not in FALLOFFS:
        raise ValueError(f"falloff: {falloff!r} is not one of {', '.join(FALLOFFS)}")
    return distortion


def _reference(
    a, n, p, t, m, camera, lights, distortion, power, scale, ambient, convention, d_c, distance, through
) -> np.ndarray:
    """``sta``'s per-pixel arithmetic in NumPy, the readable reference, over the masked pixels
    ``_BLOCK`` at a time: the pixel's vectors (``_block_vectors``), the sum over the lights
    (``_light_sums``), the falloff (``_falloff``). ``d_c`` and ``distance``: the "burley"
    falloff's lengths and bake distance (None and 0 otherwise); ``through``: the "medium"
    falloff's ``_medium_inputs`` (None otherwise)."""
    out = np.zeros(a.shape, np.float32)
    rows = {name: arrays.pixel_rows(arr) for name, arr in (("a", a), ("n", n), ("p", p))}
    flat_t = np.ascontiguousarray(t).ravel()
    out_rows = arrays.pixel_rows(out)
    idx = np.flatnonzero(m)
    colors = [np.asarray(light.color, np.float32) for light in lights]
    f32 = np.float32
    if camera.type == "ORTHO":
        view_dir, cam_pos = (-camera.forward).astype(f32), None
    else:
        view_dir, cam_pos = None, camera.position.astype(f32)

    def run(start, stop):
        # A block of consecutive pixels (the full-screen case) is read and written as slices.
        sel = arrays.block_selection(idx, start, stop)
        albedo_rows, ok, all_ok, tt, normals, views, points = _block_vectors(
            rows, flat_t, sel, convention, view_dir, cam_pos
        )
        grey, coloured = _light_sums(lights, colors, normals, views, points, distortion, power, scale, ambient)
        res = _falloff(albedo_rows, tt, normals, views, grey, coloured, d_c, distance, through)
        if not all_ok:
            res[~ok] = 0.0
        out_rows[sel] = res.view(arrays.RGB_ITEM).ravel()

    arrays.for_blocks(idx.size, _BLOCK, run)
    return out


def _block_vectors(rows, flat_t, sel, convention, view_dir, cam_pos):
    """A block's inputs: (albedo rows (B, 3), which pixels have finite inputs, whether all do,
    the translucency t in [0, 1] (0 where an input is not finite), the unit normals, the unit
    vectors towards the viewer (``view_dir``'s three scalars for an orthographic camera, else
    towards ``cam_pos``), the positions), each vector as three planar rows."""
    f32 = np.float32
    # (B, 3) rows and strided (3, B) views of them: read-only (a slice is the caller's array).
    albedo_rows = arrays.as_rows(rows["a"][sel])
    nx, ny, nz = arrays.as_rows(rows["n"][sel]).T
    px, py, pz = arrays.as_rows(rows["p"][sel]).T
    tt = flat_t[sel]
    ok = albedo_rows[:, 0] + albedo_rows[:, 1]
    for v in (albedo_rows[:, 2], nx, ny, nz, px, py, pz, tt):
        ok += v
    ok = np.isfinite(ok)
    all_ok = bool(ok.all())
    if not all_ok:
        tt = np.where(ok, tt, f32(0.0))
    tt = np.clip(tt, f32(0.0), f32(1.0))
    if convention == "thickness":
        tt = f32(1.0) - tt
        if not all_ok:
            tt[~ok] = 0.0
    nx, ny, nz, _ = norm(nx, ny, nz)
    if cam_pos is None:
        vx, vy, vz = (view_dir[k] for k in range(3))
    else:
        vx, vy, vz, _ = norm(cam_pos[0] - px, cam_pos[1] - py, cam_pos[2] - pz)
    return albedo_rows, ok, all_ok, tt, (nx, ny, nz), (vx, vy, vz), (px, py, pz)


def _light_sums(lights, colors, normals, views, points, distortion, power, scale, ambient):
    """(grey, coloured): the sum over the lights of E_L / pi (s_T lobe + a_T) per pixel, the
    lights of equal R, G, B (white ones, say) in one accumulator ``grey`` (B,) times their
    grey level, the coloured ones per channel in ``coloured`` (3, B); None where there is none."""
    f32 = np.float32
    grey = coloured = None
    for light, color in zip(lights, colors, strict=True):
        lobe = _lobe(light, normals, views, points, distortion, power, scale, ambient)
        if color[0] == color[1] == color[2]:
            if color[0] != 1:
                lobe *= color[0]
            if grey is None:
                grey = lobe
            else:
                grey += lobe
        else:
            if coloured is None:
                coloured = np.zeros((3, lobe.size), f32)
            for c in range(3):
                coloured[c] += color[c] * lobe
    return grey, coloured


def _lobe(light, normals, views, points, distortion, power, scale, ambient):
    """One light's E_L / pi (s_T max(0, V . -normalize(L + d_T N))^p_T + a_T) per pixel (B,);
    the thickness is applied once after the sum over lights."""
    f32 = np.float32
    nx, ny, nz = normals
    vx, vy, vz = views
    lx, ly, lz, irradiance = light_at(light, *points)
    d_t = f32(distortion)
    ux = d_t * nx
    ux += lx
    uy = d_t * ny
    uy += ly
    uz = d_t * nz
    uz += lz
    # V . normalize(L + d_T N), negated; |L + d_T N| kept to drop lights whose direction vanished.
    length = ux * ux
    length += uy * uy
    length += uz * uz
    np.sqrt(length, out=length)
    vdot = vx * ux
    vdot += vy * uy
    vdot += vz * uz
    inv = np.maximum(length, f32(1e-30))
    np.divide(f32(-1.0), inv, out=inv)
    vdot *= inv
    # max(0, x)^p, with p = 0 giving 1 only where x > 0; a vanished L + d_T N gives nothing.
    if power == 0:
        lobe = (vdot > 0).astype(f32)
    else:
        lobe = np.maximum(vdot, f32(0.0), out=vdot)
        lobe **= f32(power)
    vanished = length <= _EPS
    if vanished.any():
        lobe[vanished] = 0.0
    e_pi = irradiance * f32(1.0 / math.pi)
    if np.ndim(e_pi) == 0:
        lobe *= f32(scale) * e_pi
        if ambient:
            lobe += f32(ambient) * e_pi
    else:
        lobe *= f32(scale)
        lobe += f32(ambient)
        lobe *= e_pi
    return lobe


def _falloff(albedo_rows, tt, normals, views, grey, coloured, d_c, distance, through):
    """A block's result (B, 3) from the sums over the lights: through the medium (``through``),
    Burley's transmittance (``d_c``) or the translucency map ``tt`` itself, times the albedo."""
    f32 = np.float32
    if through is not None:
        table, inv_base, clip = through
        nx, ny, nz = normals
        vx, vy, vz = views
        mu = nx * vx
        mu += ny * vy
        mu += nz * vz
        trans = _lookup(table, tt, np.abs(mu))
        light = grey[:, None] if coloured is None else (coloured + (0.0 if grey is None else grey)).T
        weight = albedo_rows * inv_base
        if clip:
            weight = np.clip(weight, f32(0.0), f32(1.0))
        return weight * light * trans
    if d_c is not None:
        trans = _transmittance(tt, distance, d_c)  # (B, 3)
        light = grey[:, None] if coloured is None else (coloured + (0.0 if grey is None else grey)).T
        return albedo_rows * light * trans
    if coloured is None:
        grey *= tt
        return albedo_rows * grey[:, None]
    if grey is not None:
        coloured += grey
    coloured *= tt
    return albedo_rows * coloured.T


#: The "medium" falloff's table: slab thicknesses x = D u^2 for u uniform over [0, 1] (D the bake
#: distance; finer where thin parts pass most light), and view cosines uniform over [0, 1]. The
#: transmittance is interpolated bilinearly: within 0.01 of the light through no thickness of the
#: model it tabulates, for walks and disks
#: at bake distances of 1 to 60 mean free paths (``tests/core/test_techniques.py``; measured
#: 0.006, at Christensen-Burley's cut at 16 d and the Skin method's view interpolation).
MEDIUM_X = 129
MEDIUM_MU = 17


@functools.lru_cache(maxsize=64)
def medium_table(length_su: tuple, distance_su: float, medium) -> np.ndarray:
    """T_c(x, mu), float32 (MEDIUM_X, MEDIUM_MU, 3): ``core.optics.medium.slab_transmittance_rgb``
    through x = ``distance_su`` (i / (MEDIUM_X - 1))^2 for the view cosine mu = j / (MEDIUM_MU - 1)
    (``medium`` a ``core.optics.medium.Medium`` or None for Burley's law with d = ``length_su``)."""
    x = distance_su * np.linspace(0.0, 1.0, MEDIUM_X) ** 2
    mu = np.linspace(0.0, 1.0, MEDIUM_MU)
    xx, mm = np.meshgrid(x, mu, indexing="ij")
    walks = medium is not None and medium.walks
    tr = slab_transmittance_rgb(xx.ravel(), length_su, medium, view_cos=mm.ravel() if walks else None)
    table = np.asarray(tr, np.float32).reshape(MEDIUM_X, MEDIUM_MU, 3)
    table.flags.writeable = False
    return table


def _medium_inputs(length_su, distance_su, medium_args):
    """(table, per-channel factor of the exit weight, clip it to 1) for the "medium" falloff."""
    if length_su is None or not distance_su:
        raise ValueError(
            "falloff 'medium' reads the map as a thickness through the material: it needs mfp_su (or d_su), the"
            f" material's lengths per channel, and thickness_distance_su > 0, the bake's distance (got"
            f" {length_su!r} and {distance_su!r}); falloff 'map' needs neither"
        )
    length = tuple(float(v) for v in arrays.rgb_lengths(length_su, "mfp_su"))
    distance = arrays.positive_finite(distance_su, "thickness_distance_su", allow_zero=False)
    method, base_color, ior, anisotropy = medium_args
    medium = (
        None if method is None else Medium(method, tuple(float(v) for v in base_color), float(ior), float(anisotropy))
    )
    table = medium_table(length, float(distance), medium)
    if medium is not None and medium.walks:
        # A walk divides the closure weight by Base Color (core.optics.medium.exit_weight).
        base = np.asarray(medium.base_color, np.float64)
        inv = np.where(base > 0, 1.0 / np.maximum(base, 1e-6), 0.0).astype(np.float32)
        return table, inv, True
    return table, np.ones(3, np.float32), False


def _lookup(table: np.ndarray, translucency: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """T_c per pixel (B, 3) from ``medium_table``: bilinear in u = sqrt(x / D) (from the translucency
    t in [0, 1]: x / D = sqrt(1 - t)) and the view cosine ``mu``; the float32
    operations of ``core.techniques.sta._kernels.sta_kernel``, in its order."""
    f32 = np.float32
    sx = np.sqrt(np.sqrt(np.maximum(f32(1.0) - translucency, f32(0.0)))) * f32(MEDIUM_X - 1)
    i = np.minimum(np.floor(sx), f32(MEDIUM_X - 2)).astype(np.int64)
    fx = (sx - i.astype(f32))[:, None]
    sm = np.where(mu < f32(1.0), mu, f32(1.0)) * f32(MEDIUM_MU - 1)  # NaN reads as 1, as the kernel's
    j = np.minimum(np.floor(sm), f32(MEDIUM_MU - 2)).astype(np.int64)
    fm = (sm - j.astype(f32))[:, None]
    lo = table[i, j] + fx * (table[i + 1, j] - table[i, j])
    hi = table[i, j + 1] + fx * (table[i + 1, j + 1] - table[i, j + 1])
    return lo + fm * (hi - lo)


def _compiled(
    a, n, p, t, m, camera, lights, distortion, power, scale, ambient, convention, out, d_c, distance, through
):
    """``_reference``'s per-pixel arithmetic as one compiled kernel (``core.techniques.sta._kernels.sta_kernel``)."""
    c = np.ascontiguousarray
    args = _kernel_args(camera, lights, distortion, power, scale, ambient, convention, d_c, distance, through)
    backend.run_kernel(_kernels().sta_kernel, c(a), c(n), c(p), c(t), c(m), *args, out)


def _kernel_args(camera, lights, distortion, power, scale, ambient, convention, d_c, distance, through) -> tuple:
    """The arguments ``sta_kernel`` and ``sta_composite`` take after their frames, from ``_settings``'."""
    f32 = np.float32
    if camera.type == "ORTHO":
        view = (-camera.forward).astype(f32)
    else:
        view = camera.position.astype(f32)
    three_d = np.zeros(3, f32) if d_c is None else np.array([f32(3.0 * v) if v > 0 else 0.0 for v in d_c], f32)
    return (
        _optics_kernels().light_table(lights),
        camera.type == "ORTHO",
        view,
        f32(distortion),
        f32(power),
        f32(scale),
        f32(ambient),
        convention == "thickness",
        d_c is not None,
        f32(distance),
        three_d,
        through is not None,
        _NO_TABLE if through is None else through[0],
        np.ones(3, f32) if through is None else through[1],
        through is not None and through[2],
    )


#: Material Index values below this are float32 values exactly (2^24): the route finds a
#: material's pixels by comparing the pass rounded as float32 with its index.
_EXACT_INDEX = 1 << 24
#: The keywords ``apply`` gives ``sta`` beside a material's parameters: frames, which the route
#: reads from the passes itself.
_FRAMES = frozenset({"albedo", "normal", "position", "thickness", "mask"})


@functools.cache
def _signature() -> inspect.Signature:
    return inspect.signature(sta)


def composite(passes, scene, index: int, image: np.ndarray, sss: np.ndarray, gain, weight, params: dict):
    """STA on one material composited into ``core.pipeline.apply``'s layers in one compiled pass
    (``core.techniques.sta._kernels.sta_composite``), the same bits as ``apply``'s generic route
    (``sta`` on the pixels of the material whose inputs are finite, its result times ``gain``
    and the Subsurface Weight ``weight``, composited): the passes are read as they are, without
    cleaned copies, scans of the whole frame for NaN or the material's mask.

    ``passes`` (``core.scene.exr.Passes``) and ``scene`` (``core.scene.scene.SceneDescription``)
    as ``apply`` has them; ``index`` the material's pass index; ``image`` (H, W, C) the Image layer
    (Combined so far) and ``sss`` (H, W, 3) the SSS layer, written on the material's pixels;
    ``gain`` None, one number or three; ``weight`` None or one number; ``params`` the material's
    parameters (``sta``'s keywords). Returns (pixels of the material with an input that is not
    finite, pixels whose result is not finite, pixels clamped to no negative light), or None
    where the route does not apply (the NumPy backend, passes of another type or layout, a
    thickness AOV of several channels, an
    index beyond float32's exact integers, a gain of another shape): ``apply`` runs ``sta`` then.
    Raises ``sta``'s ValueError for a parameter that is not valid."""
    if backend.active() == "numpy" or _FRAMES & params.keys():
        return None
    frames = [passes.get(name) for name in ("Diffuse Color", "Normal", "Position")]
    thickness = passes.get(scene.thickness_aov)
    raw_index = passes.get("Material Index")
    h, w = passes.shape
    if thickness is None or raw_index is None or raw_index.shape != (h, w) or not 0 < index < _EXACT_INDEX:
        return None
    if any(a is None or a.shape != (h, w, 3) for a in frames) or thickness.shape[2:] not in ((), (1,)):
        return None
    if image.ndim != 3 or image.shape[2] < 3 or sss.shape != (h, w, 3) or image.shape[:2] != (h, w):
        return None
    inputs = [*frames, thickness, raw_index, image, sss]
    if any(a.dtype != np.float32 or not a.flags.c_contiguous for a in inputs):
        return None
    if not (image.flags.writeable and sss.flags.writeable):
        return None
    gains = np.ones(3, np.float32) if gain is None else np.asarray(gain, np.float32)
    if gains.shape not in ((), (3,)) or (weight is not None and np.ndim(weight) != 0):
        return None
    args = (
        _signature()
        .bind_partial(camera=scene.camera, lights=scene.lights, thickness_convention=scene.thickness_convention)
        .arguments
    )
    args.update(params)
    bound = _signature().bind_partial(**args)
    bound.apply_defaults()
    k = bound.arguments
    medium_args = (k["subsurface_method"], k["base_color"], k["subsurface_ior"], k["subsurface_anisotropy"])
    distortion, power, scale, ambient, d_c, distance, through = _settings(
        k["camera"], k["lights"], k["distortion"], k["power"], k["scale"], k["ambient"], k["thickness_convention"],
        k["falloff"], k["d_su"], k["thickness_distance_su"], k["mfp_su"], medium_args,
    )  # fmt: skip
    lights = [light for light in k["lights"] if light.energy > 0]
    kernel_args = _kernel_args(
        k["camera"], lights, distortion, power, scale, ambient, k["thickness_convention"], d_c, distance, through
    )
    counts = np.empty((h, 3), np.int64)
    backend.run_kernel(
        _kernels().sta_composite,
        *(a.reshape(-1) for a in frames),
        thickness.reshape(-1),
        raw_index.reshape(-1),
        np.float32(index),
        *kernel_args,
        np.array(np.broadcast_to(gains, (3,))),
        weight is not None,
        np.float32(0.0 if weight is None else weight),
        image.reshape(-1),
        np.uint64(image.shape[2]),
        sss.reshape(-1),
        w,
        np.empty(h * w, np.uint8),
        True,
        counts,
    )
    nonfinite, overflow, negative = (int(v) for v in counts.sum(axis=0))
    return nonfinite, overflow, negative


composite.computes = sta  # type: ignore[attr-defined]  # the function the route computes (Technique.composite)


#: The compiled kernel's table argument when there is none (a typed placeholder).
_NO_TABLE = np.zeros((2, 2, 3), np.float32)


def _prepare(params: dict) -> list[str]:
    """Without the bake's distance the map cannot be read as a thickness: the paper's falloff."""
    if params.get("falloff") != "medium" or params.get("thickness_distance_su"):
        return []
    params["falloff"] = "map"
    return [
        "the thickness map has no bake distance (bake it with SSS Lab's Bake Thickness): STA scales by the"
        " map itself (falloff map), not through the material's medium"
    ]


#: STA's spec (``core/techniques/spec.py``): the defaults are the signature's (three.js's distortion, power and
#: ambient, docs/references.md §4); scale 1 makes the translucency as bright as a Lambertian surface
#: facing the light; the "medium" falloff filters it as the material's Cycles method does
#: (docs/references.md §14). The comparison can still calibrate the scale with each falloff.
TECHNIQUE = Technique(
    name="sta",
    label="STA",
    description="Simple translucency: back-lighting times a baked thickness map",
    citation="docs/references.md §4; Barré-Brisebois & Bouchard 2011, Approximating Translucency for a Fast, "
    "Cheap and Convincing Subsurface Scattering Look (GDC)",
    function=sta,
    scatters=False,
    adds_light=True,
    passes=("Combined", "Diffuse Color", "Normal", "Position", "Material Index", THICKNESS),
    params=(
        Param(
            "distortion",
            "Distortion",
            "How far the surface normal bends the light direction (L + distortion N)",
            min=0.0,
            soft_max=1.0,
        ),
        Param(
            "power", "Power", "Exponent of the view-dependent back-light term (higher: tighter)", min=0.0, soft_max=16.0
        ),
        Param("scale", "Scale", "Brightness of the translucency", min=0.0, soft_max=20.0),
        Param("ambient", "Ambient", "Translucency that does not depend on the view direction", min=0.0, soft_max=1.0),
        Param(
            "falloff",
            "Falloff",
            "How the thickness map scales the translucency",
            type=str,
            choices=(
                (
                    "medium",
                    "Through the Medium",
                    "The light filtered through the slab thickness the baked map stands for, as the material's"
                    " Cycles subsurface method carries it (uses the bake distance)",
                ),
                ("map", "Map", "The paper's: the translucency map itself, the same for R, G and B"),
                (
                    "burley",
                    "Burley Transmission",
                    "Per-channel Burley transmittance through the slab thickness the baked map stands for"
                    " (uses the bake distance; red passes thick parts best)",
                ),
            ),
        ),
    ),
    # The paper's map first (the cheapest), then the default.
    qualities=({"falloff": "map"}, {}),
    default_quality=1,
    calibration={"falloff": FALLOFFS, "scale": (0.25, 0.5, 1.0, 2.0, 4.0)},
    prepare=_prepare,
    fit=("scale",),
    composite=composite,
)
