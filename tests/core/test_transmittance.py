"""core/optics/transmittance.py: the light Cycles' random walk carries through a slab (docs/references.md §14).

Expected values are closed forms evaluated here independently: the unscattered light e^{-tau/mu0}
(the table's n = 0 column), van de Hulst's semi-infinite albedo (which Cycles' inversion undoes)
and the diffusion limit of a conservative slab."""

import math

import numpy as np
import pytest

from sss_lab.core.optics import transmittance as tr
from sss_lab.core.optics.transmittance import trapezoid


def test_unscattered_light_is_the_exponential_law():
    """P_0(tau): no scattering before depth tau, e^{-tau / mu0}. The tolerance is the Monte Carlo
    error of a binomial estimate from 2^15 walks: 4 standard deviations, plus one walk's share
    where the expected count is below one."""
    for mu0 in tr.ENTRY_COSINES:
        p0 = tr.passage_table(mu0)[:, 0]
        expected = np.exp(-tr.TAUS / mu0)
        sigma = np.sqrt(expected * (1 - expected) / tr.WALKS)
        assert np.all(np.abs(p0 - expected) <= 4 * sigma + 1.0 / tr.WALKS)


def test_cycles_albedo_inversion_undoes_van_de_hulst():
    """alpha from Base Color A: van de Hulst's R(alpha) = (1 - s)(1 - 0.139 s) / (1 + 1.17 s), s =
    sqrt(1 - alpha), gives back A within the fit's accuracy (d'Eon quotes about 1e-3 absolute)."""
    a = np.linspace(0.05, 0.95, 19)
    alpha = tr.single_scattering_albedo(a)
    s = np.sqrt(1.0 - alpha)
    r = (1 - s) * (1 - 0.139 * s) / (1 + 1.17 * s)
    np.testing.assert_allclose(r, a, atol=3e-3)
    assert tr.single_scattering_albedo([1.0, 0.0, 0.5]).tolist()[0] == 0.999999


def test_conservative_slab_follows_diffusion_and_the_segment_cap():
    """alpha = 1: diffusion theory gives T = (mu0 + z_b) / (tau + 2 z_b) with z_b = 0.7104 for a
    thick slab; within 10 % at tau = 4..8 (the diffusion approximation's own accuracy there). At
    depth 64 nothing crosses in Cycles' 256 segments."""
    t = tr.passage_table(1.0).sum(axis=1)
    for tau in (4.0, 8.0):
        i = int(np.argmin(np.abs(tr.TAUS - tau)))
        expected = (1.0 + 0.7104) / (tr.TAUS[i] + 2 * 0.7104)
        assert abs(t[i] / expected - 1) < 0.1
    assert t[-1] < 1e-4


def test_transmittance_colour_comes_from_the_medium():
    """Longer path and brighter albedo pass more; T(0) = 1; thicker passes less; the alpha floor
    scales the light as Cycles does (alpha / 0.2)."""
    x = np.array([0.0, 0.002, 0.01, 0.05])
    t = tr.transmittance_rgb(x, (0.01, 0.004, 0.002), (0.6, 0.6, 0.6))
    np.testing.assert_allclose(t[0], 1.0, rtol=1e-6)
    assert np.all(np.diff(t[:, 0]) < 0) and np.all(t[1:, 0] > t[1:, 1]) and np.all(t[1:, 1] > t[1:, 2])
    pale = tr.transmittance_rgb(x, (0.004,) * 3, (0.9, 0.5, 0.1))
    assert np.all(pale[1:, 0] > pale[1:, 1]) and np.all(pale[1:, 1] > pale[1:, 2])
    low = tr.slab_transmittance(np.array([0.0, 1.0]), 0.05, 1.0)
    floor = tr.slab_transmittance(np.array([0.0, 1.0]), 0.2, 1.0)
    np.testing.assert_allclose(low, floor * 0.25, rtol=1e-12)


def test_entry_direction_and_anisotropy():
    """A grazing view refracts into a slanted path: less light through a thin slab. Forward
    scattering (g > 0) passes more light than isotropic scattering of the same medium."""
    x = np.full(3, 0.002)
    straight = tr.transmittance_rgb(x, (0.004,) * 3, (0.7,) * 3, view_cos=np.ones(3))
    grazing = tr.transmittance_rgb(x, (0.004,) * 3, (0.7,) * 3, view_cos=np.zeros(3), ior=1.4)
    assert np.all(grazing < straight)
    # The Skin method: half cosine-distributed (view-independent), half refracted about rough
    # microfacets from the view, so a grazing view passes less.
    skin_straight = tr.transmittance_rgb(x, (0.004,) * 3, (0.7,) * 3, view_cos=np.ones(3), cosine_share=0.5)
    skin_grazing = tr.transmittance_rgb(x, (0.004,) * 3, (0.7,) * 3, view_cos=np.full(3, 0.2), cosine_share=0.5)
    assert np.all(skin_grazing < skin_straight)
    forward = tr.transmittance_rgb(x * 5, (0.004,) * 3, (0.7,) * 3, anisotropy=0.6)
    iso = tr.transmittance_rgb(x * 5, (0.004,) * 3, (0.7,) * 3)
    assert np.all(forward > iso)


def test_bad_input_names_the_value():
    with pytest.raises(ValueError, match="ior: expected a finite number >= 1"):
        tr.transmittance_rgb(np.zeros(2), (1.0, 1.0, 1.0), (0.5,) * 3, ior=0.5)
    with pytest.raises(ValueError, match="cosine_share"):
        tr.transmittance_rgb(np.zeros(2), (1.0, 1.0, 1.0), (0.5,) * 3, cosine_share=2.0)
    with pytest.raises(ValueError, match="mfp_su"):
        tr.transmittance_rgb(np.zeros(2), (1.0, -1.0, 1.0), (0.5,) * 3)
    with pytest.raises(ValueError, match="entry"):
        tr.passage_table(1.5)
    assert math.isfinite(float(tr.slab_transmittance(np.array(1e9), 0.9, 1.0)))


def test_lateral_spread_of_the_walk():
    """The light-weighted RMS lateral distance at the crossing: 0 at depth 0; in a dark medium the
    unscattered light dominates and it stays small, in a bright one the light that crosses has
    wandered sideways about as far as it went down (0.7-1 times the depth at tau 1-4)."""
    assert tr.lateral_spread(np.array(0.0), 0.9) == 0.0
    taus = np.array([1.0, 2.0, 4.0])
    dark = tr.lateral_spread(taus, 0.3) / taus
    bright = tr.lateral_spread(taus, 0.99) / taus
    assert np.all(dark < bright)
    assert np.all((bright > 0.7) & (bright < 1.0))
    p, _ = tr.spread_table()
    np.testing.assert_allclose(p.sum(axis=1)[:30], tr.passage_table(1.0).sum(axis=1)[:30], atol=0.02)


def test_disk_probes_far_side():
    """Christensen-Burley's far side: T(0) = 1; the integral of p(sqrt(rho^2 + x^2)) over rho is
    x (K1(x/d) + K1(x/(3d))) / (4 d) without the 16 d truncation, here with K1(z) = int_0^inf
    e^{-z cosh t} cosh t dt by an independent quadrature (the truncation moves it by < 1 % at
    x <= 4 d); it passes more than the profile's own integral 1 - P(x)."""
    d = 0.005
    x = np.array([0.0, 0.25, 1.0, 2.0, 4.0]) * d
    t = tr.disk_transmittance_rgb(x, (d, d, d))[:, 0]
    assert t[0] == pytest.approx(1.0, abs=1e-4)
    s = np.linspace(0.0, 12.0, 120001)

    def k1(z):
        return trapezoid(np.exp(-z * np.cosh(s)) * np.cosh(s), s)

    for xi, ti in zip(x[1:], t[1:], strict=True):
        bessel = xi * (k1(xi / d) + k1(xi / (3 * d))) / (4 * d)
        assert ti == pytest.approx(bessel, rel=1e-2)
        assert ti > 0.25 * math.exp(-xi / d) + 0.75 * math.exp(-xi / (3 * d))
    assert tr.disk_transmittance_rgb(np.array([17 * d]), (d, d, d))[0, 0] == 0.0


def test_passage_columns_kept_per_medium_are_the_columns_read_again():
    # core.techniques.combined.back_light keeps each medium's passage columns (an LRU); what it hands out must be
    # the columns passage_column gives, and a caller's copy must not change what is kept.
    from sss_lab.core.techniques.combined.back_light import _passage_columns

    alphas = (0.9, 0.99, 0.5)
    entries = (tr.COSINE_ENTRY, 0.7, 1.0)
    kept = _passage_columns(alphas, entries)
    assert kept.shape == (3, 3, tr.TAUS.size)
    for c, alpha in enumerate(alphas):
        for g, entry in enumerate(entries):
            assert np.array_equal(kept[c, g], tr.passage_column(alpha, entry))
    copy = _passage_columns(alphas, entries).copy()
    copy[:] = -1.0
    assert np.array_equal(_passage_columns(alphas, entries), kept)
    with pytest.raises(ValueError):
        kept[0, 0, 0] = 2.0  # read-only: only copies leave the cache
