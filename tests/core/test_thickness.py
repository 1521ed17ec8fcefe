"""core/scene/thickness.py: settings validation, sample split, conventions, and the slab expectation
checked against an independent Monte Carlo simulation of the rays."""

import math

import numpy as np
import pytest

from sss_lab.core.scene.thickness import (
    BakeSettings,
    auto_distance_su,
    binomial_sigma,
    slab_unoccluded_fraction,
    split_samples,
    to_convention,
)


def _simulated_slab_fraction(t, d, rng, n=400_000, cosine=True):
    """Shoot rays from a face of an infinite slab into it and count those that travel at least
    ``d`` before reaching the other face (t / cos(theta) >= d). Cosine-weighted directions drawn
    by the inverse CDF of mu (cos theta = sqrt(u)), a different method from Cycles' disk lifting;
    uniform directions: cos theta = u."""
    u = rng.random(n)
    mu = np.sqrt(u) if cosine else u
    with np.errstate(divide="ignore"):
        path = np.where(mu > 0, t / mu, np.inf)
    return float(np.mean(path >= d))


@pytest.mark.parametrize("t", [0.0, 0.05, 0.1, 0.25, 0.4, 0.5, 0.8])
def test_slab_expectation_matches_simulated_rays(t):
    rng = np.random.default_rng(7)
    d = 0.5
    expected = float(slab_unoccluded_fraction(t, d))
    simulated = _simulated_slab_fraction(t, d, rng)
    # 400k independent rays: binomial sigma <= 0.5 / sqrt(4e5) = 7.9e-4; 5 sigma = 4e-3.
    assert simulated == pytest.approx(expected, abs=4e-3)
    if 0 < t < d:
        # The same test has the power to tell cosine from uniform sampling (t/D instead).
        assert abs(_simulated_slab_fraction(t, d, rng, cosine=False) - expected) > 0.02


def test_slab_expectation_closed_form_points():
    # (t/D)^2 below D, 1 from D on: exact in float64.
    np.testing.assert_array_equal(slab_unoccluded_fraction([0.0, 0.25, 0.5, 2.0], 0.5), [0.0, 0.25, 1.0, 1.0])


@pytest.mark.parametrize("bad", [0.0, -1.0, math.inf, math.nan])
def test_slab_expectation_rejects_bad_distance(bad):
    with pytest.raises(ValueError, match="distance_su"):
        slab_unoccluded_fraction(0.1, bad)


def test_slab_expectation_rejects_negative_thickness():
    with pytest.raises(ValueError, match="thickness_su"):
        slab_unoccluded_fraction([-0.1], 1.0)


def test_conventions_are_complements_and_do_not_mutate():
    ao = np.array([0.0, 0.25, 1.0], dtype=np.float32)
    np.testing.assert_array_equal(to_convention(ao, "translucency"), [1.0, 0.75, 0.0])
    thick = to_convention(ao, "thickness")
    np.testing.assert_array_equal(thick, ao)
    thick[0] = 5.0
    assert ao[0] == 0.0 and thick.dtype == np.float32
    with pytest.raises(ValueError, match="thickness convention: 'thin'"):
        to_convention(ao, "thin")


@pytest.mark.parametrize("samples", [1, 2, 5, 16, 17, 32, 100, 128, 4096])
def test_split_samples_keeps_the_product(samples):
    render, node = split_samples(samples)
    assert render * node == samples and 1 <= node <= 16
    # The node count is the largest divisor <= 16.
    assert all(samples % d for d in range(node + 1, min(samples, 16) + 1))


def test_split_samples_examples():
    assert split_samples(32) == (2, 16)
    assert split_samples(17) == (17, 1)
    assert split_samples(12) == (1, 12)


def test_auto_distance_is_a_quarter_of_the_diagonal():
    corners = [(x, y, z) for x in (0, 3) for y in (0, 4) for z in (0, 12)]
    assert auto_distance_su(corners) == 3.25  # diagonal sqrt(9 + 16 + 144) = 13
    assert auto_distance_su([(1, 1, 1)]) == 0.0
    with pytest.raises(ValueError, match="corners_su"):
        auto_distance_su([(0, 0)])


def test_binomial_sigma():
    assert float(binomial_sigma(0.5, 100)) == 0.05
    assert float(binomial_sigma(1.0, 10)) == 0.0


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("target", "texture", "bake target: 'texture'"),
        ("convention", "opacity", "thickness convention"),
        ("samples", 0, "samples: expected an integer in 1..4096, got 0"),
        ("samples", 2.5, "samples"),
        ("distance_su", -1.0, "distance_su"),
        ("distance_su", math.nan, "distance_su"),
        ("resolution_px", 0, "resolution_px"),
        ("margin_px", 65, "margin_px"),
        ("image_format", "JPEG", "image_format: 'JPEG'"),
        ("attribute_name", " ", "attribute_name"),
    ],
)
def test_settings_validation_names_the_bad_value(field, value, message):
    with pytest.raises(ValueError, match=message):
        BakeSettings(**{field: value})


def test_default_settings():
    s = BakeSettings()
    assert (s.target, s.convention, s.samples, s.only_local) == ("attribute", "translucency", 32, True)
    assert s.distance_su == 0  # automatic
    assert s.meaning.startswith("1 = thin")
    with pytest.raises(ValueError, match="image_folder"):
        BakeSettings(target="image", image_folder="")


def test_bake_source_is_checked():
    # The default follows the target: ray at the vertices, AO for an image (which ray cannot bake).
    assert BakeSettings().source == "ray" and BakeSettings(target="image").source == "ao"
    assert BakeSettings(source="ao").source == "ao" and BakeSettings(source="ray").source == "ray"
    with pytest.raises(ValueError, match="bake source: 'rays' is not one of ao, ray"):
        BakeSettings(source="rays")
    with pytest.raises(ValueError, match="use the attribute target"):
        BakeSettings(source="ray", target="image")
