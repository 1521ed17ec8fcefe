"""core/optics/profiles.py, core/pipeline/mapping.py and core/optics/kernels.py against their closed forms."""

import math

import numpy as np
import pytest

from sss_lab.core.optics import kernels, profiles
from sss_lab.core.pipeline import mapping
from sss_lab.core.scene.scene import MaterialSSS


def _integrate(f, a, b, n=200001):
    x = np.linspace(a, b, n)
    y = f(x)
    return float(np.sum((y[1:] + y[:-1]) * np.diff(x)) / 2)


def test_polar_density_is_finite_at_zero_and_integrates_to_one():
    d = 0.37
    assert profiles.burley_polar_density(0.0, d) == pytest.approx(1 / (4 * math.pi * d), rel=1e-12)
    # 2 pi times the polar density over [0, 60 d]; the tail beyond is e^{-20} small.
    total = _integrate(lambda r: 2 * math.pi * profiles.burley_polar_density(r, d), 0, 60 * d)
    assert total == pytest.approx(1.0, abs=1e-6)  # trapezoid error at this step is below 1e-8


def test_cdf_matches_the_integral_of_the_radial_pdf_and_the_truncation():
    d = 2.0
    for r in (0.1, 1.0, 5.0, 32.0):
        assert profiles.burley_cdf(r, d) == pytest.approx(
            _integrate(lambda x: profiles.burley_radial_pdf(x, d), 0, r), abs=1e-8
        )
    # Cycles' BURLEY_TRUNCATE_CDF for 16 d.
    assert profiles.burley_cdf(profiles.TRUNCATION, 1.0) == pytest.approx(0.9963790093708328, abs=1e-15)


def test_inverse_cdf_is_accurate_to_1e_12():
    xi = np.concatenate([[0.0, 1e-12, 1e-6], np.linspace(0.001, 0.999, 999), [1 - 1e-9]])
    r = profiles.burley_icdf(xi, 1.0)
    assert r[0] == 0.0
    assert np.all(np.diff(r) > 0)
    # Golubev's closed form is exact; the round trip loses only float64 rounding.
    assert np.max(np.abs(profiles.burley_cdf(r, 1.0) - xi)) < 1e-12
    with pytest.raises(ValueError, match="xi"):
        profiles.burley_icdf(1.0)


def test_profile_transmittance_and_scalings():
    assert np.isinf(profiles.burley_profile(0.0, 1.0))
    assert profiles.burley_profile(2.0, 1.0, 0.5) == pytest.approx(
        0.5 * profiles.burley_polar_density(2.0, 1.0) / 2.0, rel=1e-12
    )
    assert profiles.burley_transmittance(0.0, 1.0, 0.8) == pytest.approx(0.8)
    assert profiles.burley_transmittance(3.0, 1.0) == pytest.approx(1 - profiles.burley_cdf(3.0, 1.0))
    # Cycles' bssrdf_burley_fitting at A = 0.8 is 1.1; the memo's three fits at A = 0.5.
    assert profiles.albedo_scaling(0.8) == pytest.approx(1.1)
    assert profiles.albedo_scaling(0.5, "searchlight") == pytest.approx(1.35 + 7 * 0.3**3)
    assert profiles.albedo_scaling(0.5, "dmfp") == pytest.approx(3.5 + 100 * 0.17**4)
    with pytest.raises(ValueError, match="unknown albedo scaling 'x'"):
        profiles.albedo_scaling(0.5, "x")
    with pytest.raises(ValueError, match="d: expected"):
        profiles.burley_cdf(1.0, -1.0)
    with pytest.raises(ValueError, match="r: expected radii >= 0"):
        profiles.burley_cdf(-1.0, 1.0)


def _mat(method="RANDOM_WALK", **kw):
    return MaterialSSS(index=1, method=method, base_color=(0.8, 0.8, 0.8), subsurface_radius=(1.0, 0.2, 0.1), **kw)


def test_mapping_follows_each_methods_convention():
    rw = _mat(subsurface_scale=0.01)
    assert mapping.burley_d(rw) == pytest.approx((0.01 / 1.1, 0.002 / 1.1, 0.001 / 1.1))
    assert mapping.burley_d(rw, mapping="none") == pytest.approx((0.01, 0.002, 0.001))
    burley = _mat("BURLEY", subsurface_scale=0.01)
    assert mapping.burley_d(burley) == pytest.approx(tuple(v / (4 * math.pi) for v in (0.01, 0.002, 0.001)))
    legacy = _mat("RANDOM_WALK_LEGACY", subsurface_scale=0.01)
    assert mapping.burley_d(legacy, mapping="none") == pytest.approx(mapping.burley_d(burley))
    skin = _mat("RANDOM_WALK_SKIN", subsurface_scale=0.01, subsurface_ior=1.4)
    factor = mapping.skin_radius_factor(0.8, 1.4)
    # alpha' must reproduce the albedo through the dipole formula it inverts.
    inv = 1 / 1.4
    fdr = inv * (-1.44 * inv + 0.71) + 0.668 + 0.0636 * 1.4
    alpha = 1 - float(factor) ** 2 / 3
    assert mapping._dipole_rd(alpha, 4 / 3 * (1 + fdr) / (1 - fdr)) == pytest.approx(0.8, abs=1e-9)
    assert mapping.burley_d(skin, mapping="none")[0] == pytest.approx(0.01 * float(factor))
    for technique, key in (("ssss", "d_su"), ("burley", "d_su"), ("sta", "power")):
        assert key in mapping.technique_params(rw, technique)


def test_burley_d_kept_per_material_follows_every_value_it_reads():
    # burley_d is cached on the material's values: each one that changes d must change it, and a
    # value asked again must give what was computed (the skin's IOR and colour, the scale, the
    # mapping, the method).
    skin = _mat("RANDOM_WALK_SKIN", subsurface_scale=0.01, subsurface_ior=1.4)
    first = mapping.burley_d(skin)
    assert mapping.burley_d(skin) == first
    others = [
        _mat("RANDOM_WALK_SKIN", subsurface_scale=0.01, subsurface_ior=1.3),
        _mat("RANDOM_WALK_SKIN", subsurface_scale=0.02, subsurface_ior=1.4),
        MaterialSSS(
            index=1,
            method="RANDOM_WALK_SKIN",
            base_color=(0.5, 0.8, 0.8),
            subsurface_radius=(1.0, 0.2, 0.1),
            subsurface_scale=0.01,
            subsurface_ior=1.4,
        ),
        _mat("RANDOM_WALK", subsurface_scale=0.01, subsurface_ior=1.4),
    ]
    for other in others:
        assert mapping.burley_d(other) != first
    assert mapping.burley_d(skin, mapping="none") != first
    ell = mapping.mean_free_path(skin)
    expected = ell / profiles.albedo_scaling(skin.base_color, mapping.mapping_name(skin.method))
    assert mapping.burley_d(skin) == tuple(float(v) for v in expected)


def test_mapping_rejects_unknown_names():
    with pytest.raises(ValueError, match="unknown mapping 'foo' for subsurface method RANDOM_WALK"):
        mapping.burley_d(_mat(), mapping="foo")
    with pytest.raises(ValueError, match="unknown subsurface method"):
        mapping.mapping_name("CUBIC")
    with pytest.raises(ValueError, match="unknown technique 'blur'"):
        mapping.technique_params(_mat(), "blur")


@pytest.mark.parametrize("kind", kernels.KERNEL_TYPES)
@pytest.mark.parametrize("taps", (11, 17, 25))
def test_kernels_are_normalized_and_red_spreads_widest(kind, taps):
    k = kernels.make_kernel(kind, taps, d_su=(0.01, 0.004, 0.002))
    assert len(k) == taps
    assert np.allclose(k.weights.sum(axis=0), 1.0, atol=1e-12)
    assert np.allclose(k.offsets_su, -k.offsets_su[::-1])
    spread = k.spread_su()
    assert spread[0] > spread[1] > spread[2] > 0


def test_preintegrated_kernel_reproduces_the_profiles_line_spread():
    d = 0.01
    k = kernels.preintegrated_kernel(25, d_su=(d, d, d))
    cells = kernels._cell_integrals(kernels.footprints(k.offsets_su), d)
    # The cells cover the square of side 2 x 16.5 d: at least the 16 d disk's 0.99638.
    assert 0.99638 < cells.sum() <= 1.0
    # Marginal: each tap holds the profile's mass in its strip. Check the strips against the
    # closed form P(|X| < x) = 1 - (2/pi) int_0^{pi/2} (1 - CDF(x / cos t)) dt (midpoint rule,
    # 20000 steps: error far below the 1e-4 asked).
    t = (np.arange(20000) + 0.5) / 20000 * (math.pi / 2)
    edges = kernels.footprints(k.offsets_su)
    centre = 12
    for i in (centre, centre + 2, centre + 6):
        x0, x1 = abs(edges[i]), edges[i + 1]
        strip = [
            1 - (2 / math.pi) * np.mean(1 - profiles.burley_cdf(x / np.cos(t), d)) * (math.pi / 2) for x in (x0, x1)
        ]
        expected = (strip[1] - strip[0]) / 2 if i != centre else strip[1]
        assert k.weights[i, 0] * cells.sum() == pytest.approx(expected, abs=1e-4)


def test_rank1_preintegration_is_the_least_squares_separable_fit():
    d = 0.01
    k = kernels.preintegrated_kernel(25, d_su=(d, d, d), method="rank1")
    cells = kernels._cell_integrals(kernels.footprints(k.offsets_su), d)
    target = cells / cells.sum()
    s = np.linalg.svd(target, compute_uv=False)
    # Normalizing the singular vector to sum 1 costs a little over the optimal rank-1 error.
    assert np.linalg.norm(k.matrix(0) - target) <= 1.5 * np.sqrt((s[1:] ** 2).sum())
    marginal = kernels.preintegrated_kernel(25, d_su=(d, d, d))
    assert k.spread_su()[0] < marginal.spread_su()[0]  # the rank-1 fit spreads less
    with pytest.raises(ValueError, match="method"):
        kernels.preintegrated_kernel(25, d_su=(d, d, d), method="svd")


def test_kernel_extremes_and_bad_input():
    assert len(kernels.preintegrated_kernel(17, d_su=(0, 0, 0))) == 1
    k = kernels.preintegrated_kernel(17, d_su=(0.01, 0.0, 1e-12))
    centre = 8
    assert k.weights[centre, 1] == 1.0 and k.weights[centre, 2] == 1.0
    with pytest.raises(ValueError, match="n_taps: expected an odd integer"):
        kernels.preintegrated_kernel(16, d_su=(1, 1, 1))
    with pytest.raises(ValueError, match="d_su"):
        kernels.preintegrated_kernel(17, d_su=(-1, 1, 1))
    with pytest.raises(ValueError, match="unknown kernel type"):
        kernels.make_kernel("box", 17, d_su=(1, 1, 1))
