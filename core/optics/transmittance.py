"""How much light Cycles' random walk carries through a slab, per channel (docs/references.md §14).

The combined technique's light from behind is this function of the slab's thickness times the
irradiance on the far side. It is not a profile fitted to pictures: it is the expectation of the
random walk Cycles 5.2 runs (``kernel/integrator/subsurface_random_walk.h``, ``subsurface.h``),
computed for an infinite slab:

- the medium of each channel: extinction sigma_t = 1 / l (l the method's length,
  ``core.pipeline.mapping.mean_free_path``) and single-scattering albedo alpha from Base Color A by the
  inversion Cycles uses for its random walks (d'Eon, *A Hitchhiker's Guide to Multiple
  Scattering*, eq. 53.7): s = 4.09712 + 4.20863 A - sqrt(9.59217 + 41.6808 A + 17.7126 A^2),
  alpha = (1 - s^2) / (1 - g s^2), at most 0.999999 (Random Walk (Legacy) keeps Chiang et al.'s
  fit, ``legacy_single_scattering_albedo``); below 0.2 alpha is raised to 0.2 and the light
  scaled by alpha / 0.2, as Cycles does;
- the walk enters through the visible surface (the camera's path refracted into the medium: its
  cosine to the normal is mu0 = sqrt(1 - (1 - mu_v^2) / eta^2) for a view cosine mu_v; the Skin
  method enters half of its paths cosine-distributed and refracts the other half about GGX
  normals of roughness 1, which for a view along the normal are cosine-distributed), flies
  exponential distances, scatters isotropically (anisotropy through the similarity relation, below), and ends where it
  crosses a surface: crossing the far side of the slab, it picks up the light there with a
  diffuse (Lambert) closure, E cos / pi; at most 256 segments (``BSSRDF_MAX_BOUNCES``), after
  which the path is dropped;
- its weight is alpha^n after n scatterings; so T(tau, alpha) = sum_n P_n(tau) alpha^n with
  P_n(tau) the probability that a walk first reaches optical depth tau = x / l after exactly n
  scatterings without leaving through the front. ``passage_table`` estimates P_n once per entry
  (a fixed-seed Monte Carlo of 2^15 walks, a few seconds, cached), and every material and
  thickness then costs a polynomial in alpha and an interpolation.

Anisotropy g != 0 is folded in by the similarity relation Cycles itself switches to after nine
bounces: sigma_s* = (1 - g) sigma_s, sigma_t* = sigma_t - g sigma_s, an isotropic walk in the
reduced medium (exact in the diffusive limit, approximate for the first few scatterings).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..base import arrays

#: The trapezoid rule: ``np.trapezoid`` since NumPy 2.0, ``np.trapz`` in NumPy 1.26 (Blender 4.5).
trapezoid = getattr(np, "trapezoid", None) or getattr(np, "trapz")  # noqa: B009 (deprecated in NumPy 2)

#: Cycles' cap on random-walk segments (``BSSRDF_MAX_BOUNCES``): a path still inside after it is lost.
MAX_SEGMENTS = 256
#: Cycles' floor on the single-scattering albedo (``subsurface_random_walk_coefficients``).
MIN_ALPHA = 0.2
#: Walks per entry direction of the passage table, and its seed (the table is deterministic).
WALKS = 1 << 15
SEED = 20261127
#: Optical depths tabulated (0 and 48 steps from 0.01 to 64); beyond 64 nothing crosses in 256
#: segments at any albedo (the table's last column is below 1e-4).
TAUS = np.concatenate(([0.0], np.geomspace(0.01, 64.0, 48)))
#: Entry cosines of the refracted camera path (Snell at eta >= 1.01 keeps mu0 >= 0.14; below the
#: first value the table is read at it) and the key of the cosine-distributed entry.
ENTRY_COSINES = (0.5, 0.7, 0.85, 1.0)
COSINE_ENTRY = "cosine"
#: Key of the rough refractive entry: (ROUGH_ENTRY, ior, view cosine).
ROUGH_ENTRY = "ggx1"


def single_scattering_albedo(base_color, anisotropy: float = 0.0) -> np.ndarray:
    """Per-channel single-scattering albedo of Cycles' random walk for Base Color ``base_color``
    (the inversion of the module docstring, clipped to [0, 0.999999]); float64 (3,)."""
    a = np.clip(np.asarray(base_color, np.float64), 0.0, 1.0)
    s2 = (4.09712 + 4.20863 * a - np.sqrt(9.59217 + 41.6808 * a + 17.7126 * a * a)) ** 2
    g = float(anisotropy)
    return np.clip((1.0 - s2) / np.maximum(1.0 - g * s2, 1e-12), 0.0, 0.999999)


#: Chiang et al.'s fit as Cycles codes it (``subsurface_random_walk_remap``): each coefficient a
#: polynomial in g (powers 0..7); B and E are a constant plus a factor times e^(polynomial, powers 1..7).
_CHIANG_POLY = {
    "A": (
        1.8260523782,
        -1.28451056436,
        -1.79904629312,
        9.19393289202,
        -22.8215585862,
        32.0234874259,
        -23.6264803333,
        7.21067002658,
    ),
    "C": (
        1.09686102424,
        -0.394704063468,
        1.05258115941,
        -8.83963712726,
        28.8643230661,
        -46.8802913581,
        38.5402837518,
        -12.7181042538,
    ),
    "D": (
        0.496310210422,
        0.360146581622,
        -2.15139309747,
        17.8896899217,
        -55.2984010333,
        82.065982243,
        -58.5106008578,
        15.8478295021,
    ),
    "F": (
        2.40602999408,
        -2.51814844609,
        9.18494908356,
        -79.2191708682,
        259.082868209,
        -403.613804597,
        302.85712436,
        -87.4370473567,
    ),
}
_CHIANG_EXP = {
    "B": (
        4.98511194385,
        0.127355959438,
        (31.1491581433, -201.847017512, 841.576016723, -2018.09288505, 2731.71560286, -1935.41424244, 559.009054474),
    ),
    "E": (
        4.23190299701,
        0.00310603949088,
        (76.7316253952, -594.356773233, 2448.8834203, -5576.68528998, 7116.60171912, -4763.54467887, 1303.5318055),
    ),
}


def legacy_single_scattering_albedo(base_color, anisotropy: float = 0.0) -> np.ndarray:
    """Random Walk (Legacy)'s single-scattering albedo (Cycles ``subsurface_random_walk_remap``
    for g >= 0: Chiang et al. 2016's fit, its coefficients polynomials in g); float64 (3,)."""
    a = np.clip(np.asarray(base_color, np.float64), 0.0, 1.0)
    gp = float(anisotropy) ** np.arange(8)
    k = {name: float(gp @ np.array(c)) for name, c in _CHIANG_POLY.items()}
    for name, (const, factor, poly) in _CHIANG_EXP.items():
        k[name] = const + factor * math.exp(float(gp[1:] @ np.array(poly)))
    blend = a**0.25
    alpha = (1.0 - blend) * k["A"] * np.arctan(k["B"] * a) ** k["C"] + blend * k["D"] * np.arctan(k["E"] * a) ** k["F"]
    return np.clip(alpha, 0.0, 0.999999)


def reduced_medium(mfp, alpha, anisotropy: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(length, single-scattering albedo) of the isotropic walk equivalent to one with
    anisotropy g (the similarity relation): sigma_t* = sigma_t (1 - g alpha), alpha* = alpha
    (1 - g) / (1 - g alpha). g = 0 returns the inputs."""
    ell = np.asarray(mfp, np.float64)
    a = np.asarray(alpha, np.float64)
    g = float(anisotropy)
    if g == 0.0:
        return ell, a
    shrink = 1.0 - g * a
    return ell / np.maximum(shrink, 1e-12), a * (1.0 - g) / np.maximum(shrink, 1e-12)


def _rough_entry(rng, n: int, ior: float, view_cos: float) -> np.ndarray:
    """Cosines to the inward normal of the camera path refracted about GGX microfacet normals of
    roughness 1 (the Skin method's refractive half, ``subsurface_entry_bounce``) for a view at
    ``view_cos`` to the normal: visible normals sampled as Heitz 2018 does (at roughness 1 the
    stretched frame is the surface's), Snell with eta = 1 / ior. <= 0 where the refracted path
    points out of the surface (Cycles then drops it)."""
    mv = min(max(view_cos, 1e-4), 1.0)
    v = np.array([math.sqrt(1.0 - mv * mv), 0.0, mv])
    t1 = np.array([0.0, 1.0, 0.0]) if v[0] > 0 else np.array([1.0, 0.0, 0.0])
    t2 = np.cross(v, t1)
    r = np.sqrt(rng.random(n))
    phi = 2.0 * math.pi * rng.random(n)
    a, b = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + v[2])
    b = (1.0 - s) * np.sqrt(np.maximum(1.0 - a * a, 0.0)) + s * b
    c = np.sqrt(np.maximum(1.0 - a * a - b * b, 0.0))
    h = a[:, None] * t1 + b[:, None] * t2 + c[:, None] * v
    h[:, 2] = np.maximum(h[:, 2], 0.0)
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    eta = 1.0 / ior
    cos_hi = h @ v
    k = eta * cos_hi - np.sqrt(np.maximum(1.0 - eta * eta * (1.0 - cos_hi * cos_hi), 0.0))
    wo = -eta * v[None, :] + k[:, None] * h
    return -wo[:, 2]


@functools.lru_cache(maxsize=64)
def passage_table(entry) -> np.ndarray:
    """P[t, n]: probability that a walk entering with cosine ``entry`` (a number in (0, 1],
    ``COSINE_ENTRY`` or (``ROUGH_ENTRY``, ior, view cosine)) first reaches optical depth
    ``TAUS[t]`` after exactly n scatterings, n < ``MAX_SEGMENTS``, without leaving through its
    entry plane (a path that does not enter counts as lost). float64 (len(TAUS), MAX_SEGMENTS),
    read-only; a fixed-seed estimate from ``WALKS`` walks."""
    rng = np.random.default_rng(SEED)
    n = WALKS
    if entry == COSINE_ENTRY:
        mu = np.sqrt(rng.random(n))  # cosine-weighted hemisphere
    elif isinstance(entry, tuple) and len(entry) == 3 and entry[0] == ROUGH_ENTRY:
        mu = _rough_entry(rng, n, float(entry[1]), float(entry[2]))
    else:
        mu0 = float(entry)
        if not 0.0 < mu0 <= 1.0:
            raise ValueError(f"entry: expected a cosine in (0, 1] or {COSINE_ENTRY!r}, got {entry!r}")
        mu = np.full(n, mu0)
    entering = mu > 0  # a refraction that points out of the surface ends the path (Cycles)
    mu = mu[entering]
    z = np.zeros(mu.size)
    deepest = np.zeros(mu.size)
    alive = np.arange(mu.size)
    counts = np.zeros((len(TAUS), MAX_SEGMENTS), np.float64)
    taus = TAUS[1:]
    counts[0, 0] = mu.size  # depth 0 is reached at once
    for segment in range(MAX_SEGMENTS):
        if alive.size == 0:
            break
        step = rng.exponential(size=alive.size)
        z_new = z + mu * step
        # Depths first crossed on this segment, after `segment` scatterings.
        lo = np.searchsorted(taus, deepest, side="right")
        hi = np.searchsorted(taus, z_new, side="right")
        crossed = hi > lo
        if crossed.any():
            first = np.zeros(len(taus) + 1, np.int64)
            np.add.at(first, lo[crossed], 1)
            np.add.at(first, hi[crossed], -1)
            counts[1:, segment] += np.cumsum(first)[:-1]
        deepest = np.maximum(deepest, z_new)
        keep = (z_new > 0.0) & (deepest < taus[-1])
        alive, z, deepest = alive[keep], z_new[keep], deepest[keep]
        mu = rng.uniform(-1.0, 1.0, size=alive.size)  # isotropic scattering
    table = counts / n
    table.setflags(write=False)
    return table


@functools.lru_cache(maxsize=1)
def spread_table() -> tuple[np.ndarray, np.ndarray]:
    """(P[t, n], S[t, n]) for walks entering along the normal: P as ``passage_table(1.0)`` (an
    independent estimate) and S the same walks' squared lateral distance from the entry point
    where they first cross depth ``TAUS[t]``, summed and divided by ``WALKS`` (optical units^2).
    E[r^2] at depth tau for albedo alpha is sum_n S alpha^n / sum_n P alpha^n (``lateral_spread``)."""
    rng = np.random.default_rng(SEED + 1)
    n = WALKS
    taus = TAUS[1:]
    z, deepest = np.zeros(n), np.zeros(n)
    pos = np.zeros((n, 2))
    d = np.zeros((n, 3))
    d[:, 2] = 1.0
    counts = np.zeros((len(TAUS), MAX_SEGMENTS))
    spread = np.zeros((len(TAUS), MAX_SEGMENTS))
    counts[0, 0] = n
    for segment in range(MAX_SEGMENTS):
        if z.size == 0:
            break
        step = rng.exponential(size=z.size)
        z_new = z + d[:, 2] * step
        lo = np.searchsorted(taus, deepest, side="right")
        hi = np.searchsorted(taus, z_new, side="right")
        many = np.maximum(hi - lo, 0)
        if many.any():
            walker = np.repeat(np.arange(z.size), many)
            offset = np.arange(walker.size) - np.repeat(np.cumsum(many) - many, many)
            t_idx = lo[walker] + offset
            frac = (taus[t_idx] - z[walker]) / np.maximum(z_new[walker] - z[walker], 1e-300)
            lateral = pos[walker] + (frac * step[walker])[:, None] * d[walker, :2]
            np.add.at(counts[1:, segment], t_idx, 1.0)
            np.add.at(spread[1:, segment], t_idx, np.sum(lateral * lateral, axis=1))
        pos = pos + step[:, None] * d[:, :2]
        deepest = np.maximum(deepest, z_new)
        keep = (z_new > 0.0) & (deepest < taus[-1])
        z, deepest, pos = z_new[keep], deepest[keep], pos[keep]
        mu = rng.uniform(-1.0, 1.0, size=z.size)  # isotropic scattering
        phi = rng.uniform(0.0, 2.0 * np.pi, size=z.size)
        sin = np.sqrt(1.0 - mu * mu)
        d = np.stack([sin * np.cos(phi), sin * np.sin(phi), mu], axis=1)
    p, s = counts / n, spread / n
    p.setflags(write=False)
    s.setflags(write=False)
    return p, s


def lateral_spread(tau, alpha) -> np.ndarray:
    """RMS lateral distance (optical units) between where a walk of single-scattering albedo
    ``alpha`` enters along the normal and where it first crosses depth ``tau``, weighted by the
    light it carries (``spread_table``); float64, same shape as ``tau``; 0 at tau = 0."""
    t = np.asarray(tau, np.float64)
    rms = lateral_table(alpha)
    return np.interp(t, TAUS[: rms.size], rms, right=np.nan) if rms.size else np.zeros_like(t)


def lateral_table(alpha) -> np.ndarray:
    """``lateral_spread``'s RMS distance at ``TAUS[:n]`` for albedo ``alpha`` (n of them, float64;
    none when only depth 0 carries light): up to the last depth any walk still carries light
    to (beyond it ``lateral_spread`` gives NaN)."""
    a = max(float(alpha), MIN_ALPHA)
    powers = a ** np.arange(MAX_SEGMENTS, dtype=np.float64)
    p, s = spread_table()
    light, moment = p @ powers, s @ powers
    rms = np.sqrt(np.where(light > 1e-12, moment / np.maximum(light, 1e-300), 0.0))
    # Beyond the last depth any walk still carries: its spread grows with depth like tau.
    last = int(np.max(np.flatnonzero(light > 1e-9)))
    return rms[: last + 1] if last > 0 else rms[:0]


def slab_transmittance(tau, alpha, entry) -> np.ndarray:
    """T(tau) for one channel: the light a walk of single-scattering albedo ``alpha`` entering
    with ``entry`` carries through optical depth ``tau`` (array), with Cycles' alpha floor;
    float64, same shape as ``tau``. T(0) = 1 (above the floor); beyond the table, 0."""
    t = np.asarray(tau, np.float64)
    return np.interp(t, TAUS, passage_column(alpha, entry), right=0.0)


def passage_column(alpha, entry) -> np.ndarray:
    """T at every depth of ``TAUS`` for albedo ``alpha`` and ``entry`` (``slab_transmittance``
    reads it), float64: the passage table's polynomial in alpha, with Cycles' floor."""
    a = float(alpha)
    scale = 1.0
    if a < MIN_ALPHA:
        scale, a = a / MIN_ALPHA, MIN_ALPHA
    powers = a ** np.arange(MAX_SEGMENTS, dtype=np.float64)
    return passage_table(entry) @ powers * scale


def transmittance_rgb(
    x_su,
    mfp_su,
    base_color,
    *,
    view_cos=None,
    ior: float = 1.4,
    anisotropy: float = 0.0,
    cosine_share: float = 0.0,
    legacy: bool = False,
) -> np.ndarray:
    """Per-channel slab transmittance (..., 3) float32 through thickness ``x_su`` (scene units).

    ``mfp_su`` the method's length per channel (``core.pipeline.mapping.mean_free_path``), ``base_color``
    the material's Base Color, ``view_cos`` (same shape as ``x_su``, or None for 1) the cosine
    between the visible normal and the view, ``ior`` the index the camera's path refracts
    through, ``cosine_share`` the share of walks that enter cosine-distributed (0.5 for the Skin
    method, whose other half refracts at roughness 1 and is read for a view along the normal).
    ``legacy``: Random Walk (Legacy)'s medium (Chiang et al.'s albedo fit and, for g >= 0,
    extinction 1 / (l (1 - g))). A channel with length 0 passes light only where x = 0."""
    x = np.asarray(x_su, np.float64)
    ell, alpha = walk_medium(
        mfp_su, base_color, ior=ior, anisotropy=anisotropy, cosine_share=cosine_share, legacy=legacy
    )
    if view_cos is None:
        mu0 = np.ones_like(x)
        mu_v = np.ones_like(x)
    else:
        mu_v = np.clip(np.asarray(view_cos, np.float64), 0.0, 1.0)
        mu0 = np.sqrt(np.clip(1.0 - (1.0 - mu_v * mu_v) / (ior * ior), 0.0, 1.0))
    mu0 = np.clip(mu0, ENTRY_COSINES[0], 1.0)
    out = np.empty(x.shape + (3,), np.float32)
    for c in range(3):
        if ell[c] <= 0:
            out[..., c] = (x == 0).astype(np.float32)
            continue
        tau = x / ell[c]
        if cosine_share > 0:
            # The Skin method: half cosine-distributed, half refracted at roughness 1 (Cycles'
            # fixed value for it) from the pixel's view direction.
            rough = _interp_rough(tau, mu_v, alpha[c], round(float(ior), 2))
            out[..., c] = (1.0 - cosine_share) * rough + cosine_share * slab_transmittance(tau, alpha[c], COSINE_ENTRY)
        else:
            out[..., c] = _interp_entry(tau, mu0, alpha[c])
    return out


def walk_medium(mfp_su, base_color, *, ior, anisotropy, cosine_share, legacy) -> tuple[np.ndarray, np.ndarray]:
    """(length, single-scattering albedo) per channel, float64 (3,) each, of the isotropic walk
    ``transmittance_rgb`` reads its tables with (its arguments, checked)."""
    ell = arrays.rgb_lengths(mfp_su, "mfp_su").astype(np.float64)
    if legacy and anisotropy >= 0:
        alpha = legacy_single_scattering_albedo(base_color, anisotropy)
        ell = ell * (1.0 - anisotropy)
    else:
        alpha = single_scattering_albedo(base_color, anisotropy)
    ell, alpha = reduced_medium(ell, alpha, anisotropy)
    if not (np.isfinite(ior) and ior >= 1.0):
        raise ValueError(f"ior: expected a finite number >= 1, got {ior!r}")
    if not 0.0 <= cosine_share <= 1.0:
        raise ValueError(f"cosine_share: expected a number in [0, 1], got {cosine_share!r}")
    return ell, alpha


#: View cosines the Skin method's rough entry is tabulated at (linear in between).
ROUGH_VIEW_COSINES = (0.1, 0.3, 0.5, 0.7, 0.85, 1.0)


def _interp_rough(tau: np.ndarray, mu_v: np.ndarray, alpha: float, ior: float) -> np.ndarray:
    """T at each (tau, view cosine) for the rough refractive entry, linear in the view cosine."""
    grid = ROUGH_VIEW_COSINES
    m = np.clip(mu_v, grid[0], 1.0)
    values = [slab_transmittance(tau, alpha, (ROUGH_ENTRY, ior, g)) for g in grid]
    out = values[-1].copy()
    for i in range(len(grid) - 1):
        lo, hi = grid[i], grid[i + 1]
        sel = (m >= lo) & (m < hi)
        if sel.any():
            w = (m[sel] - lo) / (hi - lo)
            out[sel] = (1.0 - w) * values[i][sel] + w * values[i + 1][sel]
    return out


def _interp_entry(tau: np.ndarray, mu0: np.ndarray, alpha: float) -> np.ndarray:
    """T at each (tau, mu0), linear in mu0 between the tabulated entry cosines."""
    grid = ENTRY_COSINES
    values = [slab_transmittance(tau, alpha, g) for g in grid]
    out = values[-1].copy()
    for i in range(len(grid) - 1):
        lo, hi = grid[i], grid[i + 1]
        sel = (mu0 >= lo) & (mu0 < hi)
        if sel.any():
            w = (mu0[sel] - lo) / (hi - lo)
            out[sel] = (1.0 - w) * values[i][sel] + w * values[i + 1][sel]
    return out


#: Christensen-Burley: Cycles truncates the profile at 16 d (``BURLEY_TRUNCATE``).
DISK_TRUNCATE = 16.0
#: Thicknesses x / d tabulated for the disk method, and quadrature points along the probe disk.
DISK_U = np.linspace(0.0, DISK_TRUNCATE, 641)
_DISK_POINTS = 4001


@functools.lru_cache(maxsize=1)
def disk_table() -> tuple[np.ndarray, np.ndarray]:
    """(T(u), E[rho^2](u) / d^2) of Cycles' Christensen-Burley disk probes on a slab u = x / d thick.

    ``subsurface_disk.h`` samples a disk radius rho from the radial profile p(r) = (e^{-r/d} +
    e^{-r/(3d)}) / (4 d) (the profile R times 2 pi r, truncated at 16 d), probes along the normal
    and weighs each hit by p(r) / p(rho) with r its 3-D distance (the MIS over the three probe
    axes gives a plane parallel to the disk its own weight). The far side of a slab, x away, is
    hit wherever the probe reaches it, rho <= sqrt((16 d)^2 - x^2), so it receives
    T(x) = int_0^{sqrt((16 d)^2 - x^2)} p(sqrt(rho^2 + x^2)) d rho / P(16 d): more than the profile's
    own integral over that side, 1 - P(x), since the weight's radius is the 3-D one. E[rho^2]
    is the second moment of the same weight over rho (the lateral spread)."""
    cdf = 1.0 - 0.25 * math.exp(-DISK_TRUNCATE) - 0.75 * math.exp(-DISK_TRUNCATE / 3.0)
    t = np.zeros_like(DISK_U)
    m2 = np.zeros_like(DISK_U)
    for i, u in enumerate(DISK_U):
        top = math.sqrt(max(DISK_TRUNCATE**2 - u * u, 0.0))
        if top <= 0:
            continue
        rho = np.linspace(0.0, top, _DISK_POINTS)
        r = np.sqrt(rho * rho + u * u)
        p = (np.exp(-r) + np.exp(-r / 3.0)) / 4.0
        t[i] = trapezoid(p, rho) / cdf
        m2[i] = trapezoid(p * rho * rho, rho) / cdf / max(t[i], 1e-300)
    t.setflags(write=False)
    m2.setflags(write=False)
    return t, m2


def disk_transmittance_rgb(x_su, d_su) -> np.ndarray:
    """T_c (..., 3) float32 of ``disk_table`` through thickness ``x_su`` for Burley's d per channel
    (0 beyond 16 d; a channel with d = 0 passes light only where x = 0)."""
    x = np.asarray(x_su, np.float64)
    d = arrays.rgb_lengths(d_su, "transmission_d_su").astype(np.float64)
    t, _ = disk_table()
    out = np.empty(x.shape + (3,), np.float32)
    for c in range(3):
        out[..., c] = np.interp(x / d[c], DISK_U, t, right=0.0) if d[c] > 0 else (x == 0)
    return out


def disk_spread(x_su, d) -> np.ndarray:
    """RMS lateral distance (scene units) of ``disk_table``'s far-side weight at thickness ``x_su``
    for Burley's d (one channel); 0 where d = 0."""
    x = np.asarray(x_su, np.float64)
    if d <= 0:
        return np.zeros_like(x)
    _, m2 = disk_table()
    return np.sqrt(np.interp(x / d, DISK_U, m2, right=0.0)) * d
