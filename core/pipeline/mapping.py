"""From a Principled BSDF's subsurface inputs to each technique's parameters.

So that the passes are driven by the same material that Cycles renders, every technique reads
its scattering distance from the material's Subsurface Radius x Subsurface Scale, Base Color
and (for the Skin method) Subsurface IOR, through the convention of the material's subsurface
method in Cycles (Blender 5.2; Cycles ``kernel/closure/bssrdf.h``, docs/references.md §2):

- BURLEY: Cycles' ``bssrdf_setup_radius`` scales the radius by 1 / (4 pi) and uses the result as
  the profile's d, with no albedo fit (the ``bssrdf_burley_fitting`` function is no longer
  called). Default mapping ``none``: d = radius / (4 pi).
- RANDOM_WALK_LEGACY (Cycles' fixed-radius random walk): mean free path l = radius / (4 pi).
- RANDOM_WALK (the 5.2 default): l = radius.
- RANDOM_WALK_SKIN: l = radius x sqrt(3 (1 - alpha')), alpha' from the dipole fit that uses the
  Subsurface IOR (Cycles' ``bssrdf_dipole_compute_alpha_prime``).

A random walk is a volume, not a profile: the Burley d that best matches it is uncertain, so it
is a documented choice among the albedo scalings of Christensen & Burley (d = l / s(A),
``profiles.ALBEDO_SCALINGS``) or none (d = l). ``MAPPINGS`` lists the choices per method, the
default first; the comparison (``blender/compare.py``) measures each against Cycles.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..optics.profiles import ALBEDO_SCALINGS, MIN_RADIUS, albedo_scaling
from ..scene.scene import SUBSURFACE_METHODS, MaterialSSS
from ..techniques import registry
from .fit_params import OFF, fitted

#: Subsurface method -> mapping names, the default first. A name is an albedo scaling of
#: ``profiles.ALBEDO_SCALINGS`` (d = l / s(A)) or "none" (d = l).
MAPPINGS: dict[str, tuple[str, ...]] = {
    "BURLEY": ("none", "diffuse_transmission", "searchlight"),
    "RANDOM_WALK": ("diffuse_transmission", "searchlight", "dmfp", "none"),
    "RANDOM_WALK_SKIN": ("diffuse_transmission", "searchlight", "dmfp", "none"),
    "RANDOM_WALK_LEGACY": ("diffuse_transmission", "searchlight", "dmfp", "none"),
}
assert set(MAPPINGS) == set(SUBSURFACE_METHODS)


def _dipole_rd(alpha_prime, fourthird_a):
    s = np.sqrt(3.0 * (1.0 - alpha_prime))
    return 0.5 * alpha_prime * (1.0 + np.exp(-fourthird_a * s)) * np.exp(-s)


def skin_radius_factor(albedo, ior: float) -> np.ndarray:
    """sqrt(3 (1 - alpha')) per channel: how Cycles' Skin method rescales the radius.

    alpha' solves Rd(alpha') = albedo for the dipole diffuse reflectance with Jensen's F_dr(eta)
    (Cycles ``bssrdf_dipole_compute_alpha_prime``; bisection, solved here to 1e-12 instead of its
    12 steps). Albedo below 1e-4 gives alpha' = 0, at or above 0.995 gives 0.999999, as there.
    """
    if not (math.isfinite(ior) and ior > 0):
        raise ValueError(f"subsurface_ior: expected a finite number > 0, got {ior!r}")
    if np.ndim(albedo) == 1 and len(albedo) == 3:
        # A material's colour: solved once per (colour, IOR); every plan of every frame asks again.
        return np.array(_skin_factor_rgb(tuple(float(v) for v in albedo), float(ior)))
    return _skin_factor(albedo, ior)


@functools.lru_cache(maxsize=1024)
def _skin_factor_rgb(albedo: tuple, ior: float) -> tuple:
    return tuple(float(v) for v in _skin_factor(albedo, ior))


def _skin_factor(albedo, ior: float) -> np.ndarray:
    a = np.clip(np.asarray(albedo, dtype=np.float64), 0.0, 1.0)
    inv = 1.0 / ior
    f_dr = inv * (-1.440 * inv + 0.710) + 0.668 + 0.0636 * ior
    fourthird_a = (4.0 / 3.0) * (1.0 + f_dr) / (1.0 - f_dr)
    lo, hi = np.zeros_like(a), np.ones_like(a)
    for _ in range(45):
        mid = 0.5 * (lo + hi)
        below = _dipole_rd(mid, fourthird_a) < a
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    alpha = 0.5 * (lo + hi)
    alpha = np.where(a < 1e-4, 0.0, np.where(a >= 0.995, 0.999999, alpha))
    return np.sqrt(3.0 * (1.0 - alpha))


def mean_free_path(material: MaterialSSS) -> np.ndarray:
    """The per-channel length Cycles gives the material's subsurface method (scene units)."""
    m = material
    return _mean_free_path(m.method, np.asarray(m.radius, dtype=np.float64), m.base_color, m.subsurface_ior)


def _mean_free_path(method: str, radius: np.ndarray, base_color, ior: float) -> np.ndarray:
    """``mean_free_path`` of a material's method, radius (scene units), Base Color and IOR."""
    if method in ("BURLEY", "RANDOM_WALK_LEGACY"):
        return radius / (4.0 * math.pi)
    if method == "RANDOM_WALK":
        return radius
    if method == "RANDOM_WALK_SKIN":
        return radius * skin_radius_factor(base_color, ior)
    raise ValueError(f"unknown subsurface method {method!r}; expected one of: {', '.join(SUBSURFACE_METHODS)}")


def mapping_name(method: str, mapping=None) -> str:
    """The mapping used for ``method``: ``mapping`` may be None (the default), one name for every
    method, or a dict method -> name. Unknown names raise ValueError listing the known ones."""
    if method not in MAPPINGS:
        raise ValueError(f"unknown subsurface method {method!r}; expected one of: {', '.join(MAPPINGS)}")
    if mapping is None:
        return MAPPINGS[method][0]
    if isinstance(mapping, dict):
        unknown = sorted(set(mapping) - set(MAPPINGS))
        if unknown:
            raise ValueError(f"mapping: unknown subsurface method(s) {unknown}; expected: {', '.join(MAPPINGS)}")
        name = mapping.get(method, MAPPINGS[method][0])
    else:
        name = mapping
    if name not in MAPPINGS[method]:
        raise ValueError(
            f"unknown mapping {name!r} for subsurface method {method}; expected one of: {', '.join(MAPPINGS[method])}"
        )
    return name


def burley_d(material: MaterialSSS, *, mapping=None) -> tuple[float, float, float]:
    """Burley's d per channel (scene units) for the material under the chosen mapping."""
    m = material
    radius, color = tuple(float(v) for v in m.radius), tuple(float(v) for v in m.base_color)
    return _burley_d(m.method, mapping_name(m.method, mapping), radius, color, float(m.subsurface_ior))


@functools.lru_cache(maxsize=1024)
def _burley_d(method: str, name: str, radius: tuple, base_color: tuple, ior: float) -> tuple[float, float, float]:
    """``burley_d`` of a material's values (every technique's parameters ask again for each
    material and frame: ``core.pipeline.auto`` reads them for each candidate)."""
    r, g, b = (float(v) for v in _d_of(method, name, radius, base_color, ior))
    return r, g, b


def _d_of(method: str, name: str, radius, base_color, ior: float) -> np.ndarray:
    """d per channel (float64, the shape of ``radius``: (3,) or (n, 3)) from the method's length
    (``_mean_free_path``) and mapping ``name`` (an albedo scaling or "none"); below ``MIN_RADIUS``, 0."""
    ell = _mean_free_path(method, np.asarray(radius, dtype=np.float64), base_color, ior)
    if name == "none":
        d = ell
    else:
        assert name in ALBEDO_SCALINGS
        d = ell / albedo_scaling(base_color, name)
    return np.where(d < MIN_RADIUS, 0.0, d)


def burley_d_pixels(method: str, radius_su: np.ndarray, base_color: np.ndarray, ior: float, mapping=None):
    """``burley_d`` for many points at once: ``radius_su`` (n, 3) Radius x Scale in scene units and
    ``base_color`` (n, 3) per point, the method's mapping; (n, 3) float64."""
    return _d_of(method, mapping_name(method, mapping), radius_su, np.asarray(base_color, np.float64), ior)


def technique_params(material: MaterialSSS, technique, *, mapping=None, use_fit: bool = True) -> dict:
    """Keyword parameters of ``technique`` (a name or a ``Technique`` spec) for ``material``
    (without the passes): its parameters' defaults (the function's signature) plus what the
    material gives every technique that takes it.

    ``d_su`` is the profile's d per channel in scene units: Burley gathers over it, SSSS builds
    its kernel from it (``core.optics.kernels``), both reaching 16 d (the truncation shared with
    Cycles), STA's "burley" falloff and the combined technique's transmittance read it.
    ``thickness_distance_su`` is the bake distance the thickness map stands for;
    ``subsurface_method`` the Cycles method whose entry energy the diffusions keep
    (``core.optics.energy``). When the
    material carries a fit for ``technique`` (``MaterialSSS.fit``, made by ``core/study/fit.py``) and
    ``use_fit`` is true, its values replace the defaults: d times ``d_scale``, the
    transmission's scale and d, STA's scale, and ``gain`` (applied by ``core.pipeline.apply`` to the
    technique's result when its function does not take it). With ``d_scale``, ``plan_d_su`` is the
    material's own d (for a technique that takes it: Burley's adaptive plan reads its footprints
    from it), so that the samples each pixel takes are the ones ``core/study/fit.py`` fitted with,
    whatever the scale it found.
    """
    spec = registry.get_spec(technique)
    d = burley_d(material, mapping=mapping)
    fit = fitted(material.fit, spec.name) if use_fit else {}
    own_d = d
    if "d_scale" in fit:
        d = tuple(v * fit["d_scale"] for v in d)
    from_material = {
        "d_su": d,
        "thickness_distance_su": material.thickness_distance,
        # The light from behind follows Cycles' own medium (core/optics/transmittance.py).
        "mfp_su": tuple(float(v) for v in mean_free_path(material)),
        "subsurface_method": material.method,
        "base_color": tuple(material.base_color),
        "subsurface_ior": material.subsurface_ior,
        "subsurface_anisotropy": material.subsurface_anisotropy,
    }
    if "d_scale" in fit:
        from_material["plan_d_su"] = own_d
    params = dict(spec.defaults)
    params.update({k: v for k, v in from_material.items() if k in spec.keywords})
    params.update({k: v for k, v in fit.items() if k not in ("d_scale", OFF)})
    return params
