"""The arithmetic of matching EEVEE to Cycles (``core/study/eevee_match.py``), without Blender."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sss_lab.core.study import eevee_match as em


def test_eevee_d_is_radius_times_scale_over_4pi_over_the_albedo_scaling():
    radius, scale, color = (1.0, 0.35, 0.2), 0.012, (0.8, 0.52, 0.42)
    # Christensen-Burley's diffuse-surface-transmission fit, written out: s = 1.9 - A + 3.5 (A - 0.8)^2.
    s = [1.9 - a + 3.5 * (a - 0.8) ** 2 for a in color]
    expected = [r * scale / (4 * math.pi) / si for r, si in zip(radius, s, strict=True)]
    np.testing.assert_allclose(em.eevee_d(radius, scale, color), expected, rtol=1e-12)


def test_eevee_radius_inverts_eevee_d():
    color = (0.9, 0.3, 0.05)
    d = np.array([0.004, 0.001, 0.0002])
    radius = em.eevee_radius(d, 0.5, color)
    np.testing.assert_allclose(em.eevee_d(radius, 0.5, color), d, rtol=1e-12)
    with pytest.raises(ValueError, match="scale: expected a number > 0, got 0"):
        em.eevee_radius(d, 0.0, color)


def _frame(seed=3, shape=(16, 16)):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.2, 1.0, shape + (3,))


def test_solve_gain_recovers_the_gain_of_a_linear_image():
    rest, light = 0.1 * _frame(1), _frame(2)
    truth = np.array([1.3, 0.9, 0.6])
    target = rest + truth * light
    keep = em.material_blocks(np.ones((16, 16), bool))
    gain, error = em.solve_gain(rest + light, rest, target, keep)
    # Closed form on exact data: rounding is the only error.
    np.testing.assert_allclose(gain, truth, rtol=1e-12)
    assert error < 1e-12
    # Bounded like the fit's gains, and a channel without scattered light keeps 1.
    far, _ = em.solve_gain(rest + light, rest, rest + 10 * light, keep)
    np.testing.assert_allclose(far, em.GAIN_RANGE[1])
    dark = light.copy()
    dark[..., 2] = 0
    g, _ = em.solve_gain(rest + dark, rest, target, keep)
    assert g[2] == 1.0


def test_effect_removed_is_the_share_of_cycles_effect_reproduced():
    keep = em.material_blocks(np.ones((16, 16), bool))
    c_none, e_none = _frame(4), 0.7 * _frame(5)
    effect = 0.2 * _frame(6)
    c_sss = c_none + effect
    assert em.effect_removed(e_none + effect, e_none, c_sss, c_none, keep) == pytest.approx(1.0)
    assert em.effect_removed(e_none, e_none, c_sss, c_none, keep) == pytest.approx(0.0)
    assert em.effect_removed(e_none + 0.5 * effect, e_none, c_sss, c_none, keep) == pytest.approx(0.5)
    assert em.effect_removed(e_none - effect, e_none, c_sss, c_none, keep) == pytest.approx(-1.0)
    assert em.effect_removed(e_none, e_none, c_none, c_none, keep) is None  # no effect to reproduce
    # What EEVEE should show: its own image without scattering plus Cycles' effect.
    np.testing.assert_allclose(em.target_image(e_none, c_sss, c_none), e_none + effect)


def test_the_view_ramp_reads_the_entry_gain_between_its_stops():
    from sss_lab.core.optics.energy import entry_gain

    albedo = (0.8, 0.45, 0.2)
    mu, factors = em.view_table("RANDOM_WALK", albedo)
    assert np.all(np.diff(mu) > 0) and mu[-1] == pytest.approx(1.0) and len(mu) <= 32  # a Color Ramp's stops
    np.testing.assert_allclose(factors.max(axis=0), 1.0)
    cos = np.linspace(0.1, 1.0, 37).reshape(1, -1)
    gain = entry_gain("RANDOM_WALK", np.broadcast_to(albedo, cos.shape + (3,)), cos)
    ratio = gain / em.view_factor(cos, (mu, factors))
    # Linear between the table's own view angles: the ramp is the gain up to one factor per channel.
    np.testing.assert_allclose(ratio, np.broadcast_to(ratio[:, :1], ratio.shape), rtol=1e-5)
    # Seen straight on, a random walk returns less than at a grazing angle (docs/references.md §15).
    assert np.all(em.view_factor(np.array([[1.0]]), (mu, factors)) < em.view_factor(np.array([[0.2]]), (mu, factors)))
    assert em.view_table("BURLEY", albedo) is None  # Christensen-Burley: equal to Lambert at every angle
