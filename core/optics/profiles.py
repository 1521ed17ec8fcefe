"""The Christensen-Burley normalized diffusion profile and its sampling, in NumPy.

Source: Christensen & Burley, "Approximate Reflectance Profiles for Efficient Subsurface
Scattering", Pixar technical memo 15-04 (2015), equations (3) and (5)-(8); Golubev, "Efficient
Screen-Space Subsurface Scattering Using Burley's Normalized Diffusion in Real-Time" (SIGGRAPH
2018) for the closed-form inverse CDF; Cycles ``kernel/closure/bssrdf.h`` for the truncation
(docs/references.md §1).

The profile R(r) = A (e^{-r/d} + e^{-r/3d}) / (8 pi d r) has a pole at r = 0, so everything here
works in the polar measure (r R(r), finite) or with the radial pdf, as every production
implementation does (docs/references.md §5). ``d`` is the shape parameter in scene units.
"""

from __future__ import annotations

import math

import numpy as np

#: Kernels end at 16 d (Cycles' and EEVEE's BURLEY_TRUNCATE), where the CDF is 0.99638.
TRUNCATION = 16.0

#: Radii and shape parameters below this are treated as zero (Cycles' BSSRDF_MIN_RADIUS is 1e-8).
MIN_RADIUS = 1e-8


def _as_float(x, what: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.dtype.kind not in "fiu":
        raise ValueError(f"{what}: expected numbers, got {x!r}")
    return a


def _check_d(d) -> np.ndarray:
    d = _as_float(d, "d")
    if np.any(~np.isfinite(d)) or np.any(d <= 0):
        raise ValueError(f"d: expected finite shape parameters > 0, got {d!r}")
    return d


def _check_r(r) -> np.ndarray:
    r = _as_float(r, "r")
    if np.any(r < 0):
        raise ValueError(f"r: expected radii >= 0, got min {float(np.min(r))!r}")
    return r


def burley_polar_density(r, d):
    """r R(r) / A = (e^{-r/d} + e^{-r/3d}) / (8 pi d): the profile in the polar measure.

    Finite at r = 0 (1 / (4 pi d)); integrating it times 2 pi dr over [0, inf) gives 1.
    """
    r, d = _check_r(r), _check_d(d)
    e3 = np.exp(-r / (3.0 * d))
    return (e3 * e3 * e3 + e3) / (8.0 * math.pi * d)


def burley_radial_pdf(r, d):
    """The pdf of the radius, 2 pi r R(r) / A = (e^{-r/d} + e^{-r/3d}) / (4 d)."""
    return 2.0 * math.pi * burley_polar_density(r, d)


def burley_profile(r, d, albedo=1.0):
    """R(r) = A (e^{-r/d} + e^{-r/3d}) / (8 pi d r), per unit area.

    At r = 0 the profile is infinite (the pole of the paper's equation 3); it is returned as
    +inf there rather than a NaN. Use ``burley_polar_density`` for anything that integrates.
    """
    r = _check_r(r)
    dens = burley_polar_density(r, d)
    with np.errstate(divide="ignore"):
        return np.asarray(albedo, dtype=np.float64) * np.where(r > 0, dens / np.where(r > 0, r, 1.0), np.inf)


def burley_cdf(r, d):
    """P(r) = 1 - e^{-r/d}/4 - 3 e^{-r/3d}/4: the fraction of the profile's energy within r."""
    r, d = _check_r(r), _check_d(d)
    e3 = np.exp(-r / (3.0 * d))
    return 1.0 - 0.25 * e3 * e3 * e3 - 0.75 * e3


def burley_icdf(xi, d=1.0):
    """The radius r with P(r) = xi, in closed form (Golubev 2018).

    With u = 1 - xi and G = 1 + 4u (2u + sqrt(1 + 4u^2)),
    r / d = 3 ln((1 + G^{-1/3} + G^{1/3}) / (4u)). ``xi`` must lie in [0, 1); xi = 0 gives 0.
    Accurate to about 1e-15 relative (checked against ``burley_cdf`` in the tests).
    """
    xi = _as_float(xi, "xi")
    if np.any(~np.isfinite(xi)) or np.any(xi < 0) or np.any(xi >= 1):
        raise ValueError(f"xi: expected probabilities in [0, 1), got {xi!r}")
    d = _check_d(d)
    u = 1.0 - xi
    g = 1.0 + 4.0 * u * (2.0 * u + np.sqrt(1.0 + 4.0 * u * u))
    g3 = np.cbrt(g)
    x = 3.0 * np.log((1.0 + 1.0 / g3 + g3) / (4.0 * u))
    # Rounding can leave -1e-16 near xi = 0.
    return np.maximum(x, 0.0) * d


def burley_transmittance(thickness, d, albedo=1.0):
    """Light through a slab of ``thickness``: T(t) = (A/4)(e^{-t/d} + 3 e^{-t/3d})
    (HDRP's ComputeTransmittanceDisney, docs/references.md §4); T(0) = A, 1 - CDF at t."""
    t = _check_r(thickness)
    d = _check_d(d)
    e3 = np.exp(-t / (3.0 * d))
    return np.asarray(albedo, dtype=np.float64) * 0.25 * (e3 * e3 * e3 + 3.0 * e3)


# --- Albedo scalings s(A): d = l / s(A) for a mean free path l (Christensen & Burley 2015) ---


def _searchlight(a):
    return 1.85 - a + 7.0 * np.abs(a - 0.8) ** 3


def _diffuse_transmission(a):
    return 1.9 - a + 3.5 * (a - 0.8) ** 2


def _dmfp(a):
    return 3.5 + 100.0 * (a - 0.33) ** 4


#: name -> (s(A), description with its source and fit error).
ALBEDO_SCALINGS = {
    "searchlight": (_searchlight, "perpendicular (searchlight) configuration, eq. 5; about 5.5 % error"),
    "diffuse_transmission": (
        _diffuse_transmission,
        "diffuse surface transmission, eq. 6 (Cycles' bssrdf_burley_fitting, EEVEE); about 3.9 % error",
    ),
    "dmfp": (_dmfp, "with the diffuse mean free path, eq. 8 (Unreal); about 7.7 % error"),
}


def albedo_scaling(albedo, scaling: str = "diffuse_transmission") -> np.ndarray:
    """s(A) of the named fit; the albedo is clamped to [0, 1] first (HDR albedo is not physical)."""
    if scaling not in ALBEDO_SCALINGS:
        raise ValueError(f"unknown albedo scaling {scaling!r}; expected one of: {', '.join(ALBEDO_SCALINGS)}")
    a = np.clip(_as_float(albedo, "albedo"), 0.0, 1.0)
    return ALBEDO_SCALINGS[scaling][0](a)


def d_from_mean_free_path(mean_free_path, albedo, scaling: str = "diffuse_transmission") -> np.ndarray:
    """d = l / s(A) per channel (Christensen & Burley 2015, section 5)."""
    ell = _as_float(mean_free_path, "mean_free_path")
    if np.any(~np.isfinite(ell)) or np.any(ell < 0):
        raise ValueError(f"mean_free_path: expected finite values >= 0, got {mean_free_path!r}")
    return ell / albedo_scaling(albedo, scaling)
