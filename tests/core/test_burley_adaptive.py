"""Burley's adaptive sample counts (core/techniques/burley/adaptive.py): where they fall and rise,
that both backends take the same samples on any number of threads, and how far the result is
from the fixed spiral's.

Every call below runs in check mode (tests/core/conftest.py): the NumPy reference and the
compiled kernel are compared within ``core.techniques.burley.technique._check_bound``, the bound
Burley's check mode has always used. A pixel taking another count on the two backends would
differ by the sampling noise (percents), far beyond that float32 bound, so check mode passing is
the two backends taking the same samples.
"""

import inspect
import math

import numba
import numpy as np
import pytest

from sss_lab.core.compute import backend
from sss_lab.core.optics.profiles import TRUNCATION
from sss_lab.core.scene.scene import Camera
from sss_lab.core.study.synthetic import sphere_scene
from sss_lab.core.techniques.burley import adaptive
from sss_lab.core.techniques.burley.technique import burley, sample_counts
from sss_lab.core.techniques.combined.technique import combined
from sss_lab.core.techniques.registry import TECHNIQUES

N = 192


def _inputs(kind, footprint_px, n=N):
    """A flat white surface under an orthographic camera (1 px per scene unit), Burley's red
    footprint (16 d) ``footprint_px`` (green and blue narrower), lit by ``kind``: "flat" (0.7
    everywhere), "edge" (a slanted straight shadow edge through the centre, 1.05 on one side and
    0.05 on the other) or "smooth" (a slow sine pattern between 0.1 and 1). Returns Burley's
    keyword arguments and each pixel's signed distance to the edge (px)."""
    cam = Camera(type="ORTHO", width_px=n, height_px=n, ortho_scale=float(n))
    d = footprint_px / TRUNCATION
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float64)
    dist = ((xx - n / 2) + 0.3 * (yy - n / 2)) / np.hypot(1.0, 0.3)
    if kind == "flat":
        value = np.full((n, n), 0.7)
    elif kind == "edge":
        value = np.where(dist < 0, 1.05, 0.05)
    else:
        value = 0.55 + 0.45 * np.sin(2 * np.pi * xx / 96.0) * np.cos(2 * np.pi * yy / 128.0)
    light = np.repeat(value[..., None], 3, axis=2).astype(np.float32)
    kw = dict(
        diffuse=light,
        albedo=np.ones_like(light),
        depth=np.ones((n, n), np.float32),
        mask=np.ones((n, n), bool),
        camera=cam,
        d_su=(d, 0.6 * d, 0.3 * d),
        adaptive=True,  # the default, named: these tests are about the plan
    )
    return kw, dist


def test_the_ladder_runs_from_one_to_the_most_samples():
    assert adaptive.ladder(32).tolist() == [1, 2, 3, 4, 6, 8, 12, 16, 23, 32]
    assert adaptive.ladder(1).tolist() == [1]
    assert adaptive.ladder(64)[-1] == 64 and adaptive.ladder(64)[0] == 1


def test_flat_light_takes_one_sample_and_keeps_its_value():
    kw, _ = _inputs("flat", 60.0)
    counts = sample_counts(**kw)
    # No variation under any footprint: the self-normalized mean of equal values needs one sample.
    assert (counts == 1).all()
    out = burley(**kw, energy="lambert")
    # One weighted value over its weight: the light itself up to the division's rounding.
    np.testing.assert_allclose(out, 0.7, rtol=4 * 2.0**-24)


@pytest.mark.parametrize("footprint_px", (1.5, 2.0, 3.0))
def test_tiny_footprints_take_few_samples_even_at_an_edge(footprint_px):
    kw, dist = _inputs("edge", footprint_px)
    counts = sample_counts(**kw)
    ladder = adaptive.ladder(32)
    # At most ceil(F^2) samples, rounded up to the ladder: 3, 4 and 9 -> 12.
    most = int(ladder[np.searchsorted(ladder, math.ceil(footprint_px**2))])
    assert counts.max() == most  # the edge's pixels take all the footprint allows
    assert counts.max() < 32


def test_counts_rise_at_a_shadow_edge_and_fall_away_from_it():
    footprint = 40.0
    kw, dist = _inputs("edge", footprint)
    counts = sample_counts(**kw)
    assert (counts[np.abs(dist) < 8] == 32).all()
    # Beyond the variation's window (a square of whole blocks reaching the footprint from the
    # block: its corner up to sqrt 2 (footprint + a block) away, plus the pixel's place in its
    # block) the light is uniform: one sample.
    far = np.abs(dist) > math.sqrt(2) * (footprint + adaptive.BLOCK_PX) + adaptive.BLOCK_PX
    assert far.sum() > 1000
    assert (counts[far] == 1).all()
    # The same counts for any seed or rotation: they depend on the inputs only.
    assert np.array_equal(counts, sample_counts(**kw, seed=9, random_rotation=False))


def test_adaptive_counts_are_the_default():
    for fn in (burley, sample_counts, combined):
        assert inspect.signature(fn).parameters["adaptive"].default is True
    assert TECHNIQUES["burley"].defaults["adaptive"] is True
    assert TECHNIQUES["combined"].defaults["adaptive"] is True
    kw, _ = _inputs("edge", 40.0)
    del kw["adaptive"]
    counts = sample_counts(**kw)
    assert counts.max() == 32 and counts.min() == 1
    np.testing.assert_array_equal(burley(**kw, energy="lambert"), burley(**kw, adaptive=True, energy="lambert"))


def test_more_samples_ask_for_a_smaller_error_and_fewer_for_a_larger():
    """``n_samples`` is the quality asked for: the plan at n takes about n / 32 times the samples
    it takes at 32 (the error target ERROR x sqrt(32 / n), the footprint's limit F^2 n / 32),
    within the ladder's rounding (sqrt 2) and at most n. On the sine pattern at a 10 px footprint
    (every pixel between 3 and 32 samples at 32, none at either end) the means came out 1.00 to
    1.03 times n / 32."""
    kw, _ = _inputs("smooth", 10.0)
    at32 = sample_counts(**kw).astype(np.float64)
    assert at32.min() > 1 and at32.mean() < 32
    for n in (8, 128, 1024):
        counts = sample_counts(**kw, n_samples=n).astype(np.float64)
        assert counts.max() <= n
        if n > 32:
            assert (counts >= at32).all()
        ratio = counts.mean() / at32.mean() / (n / 32)
        assert 1 / math.sqrt(2) <= ratio <= math.sqrt(2), (n, ratio)
    # A footprint of 2 px: ceil(F^2) = 4 samples at 32 (the edge would take all 32), F^2 n / 32 at n.
    kw, _ = _inputs("edge", 2.0)
    assert sample_counts(**kw).max() == 4
    assert sample_counts(**kw, n_samples=1024).max() == 128


def test_fixed_sampling_stays_available():
    kw, _ = _inputs("edge", 40.0)
    assert (sample_counts(**{**kw, "adaptive": False}, n_samples=24) == 24).all()
    fixed = burley(**{**kw, "adaptive": False}, energy="lambert")
    assert not np.array_equal(fixed, burley(**kw, energy="lambert"))


def test_block_sums_are_the_same_on_both_backends():
    """The plan reads the blocks' sums; the compiled kernel must give the reference's to the bit
    (sums in the same order), else a block near a threshold could take another count."""
    rng = np.random.default_rng(3)
    h, w = 37, 53  # not multiples of the block: the last blocks are partial
    light = rng.random((h, w, 3), np.float32) * 4
    ok = rng.random((h, w)) < 0.7
    depth = rng.random((h, w), np.float32) + 0.5
    shape = (-(-(h - 5) // 8), -(-(w - 3) // 8))
    with backend.use("numpy"):
        reference = adaptive.block_sums(light, ok, depth, 5, 3, 8, shape)
    with backend.use("numba"):
        compiled = adaptive.block_sums(light, ok, depth, 5, 3, 8, shape)
    for a, b in zip(reference, compiled, strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("kind", ("edge", "smooth"))
def test_numpy_and_compiled_agree_within_the_check_bound(kind):
    kw, _ = _inputs(kind, 40.0)
    # Check mode raises BackendMismatch beyond _check_bound; the clean-up off and on.
    burley(**kw, smooth_px=0, energy="lambert")
    burley(**kw, energy="lambert")


def test_numpy_and_compiled_agree_on_objects_and_combined():
    """Several objects (one spiral per object and count), perspective depth, the combined
    technique's gather (it calls Burley's)."""
    passes, scene = sphere_scene(96, 64)
    light = passes["Diffuse Direct"] + passes["Diffuse Indirect"]
    kw = dict(
        diffuse=light,
        albedo=passes["Diffuse Color"],
        depth=passes["Depth"],
        mask=passes["Material Index"] > 0,
        camera=scene.camera,
        d_su=(0.02, 0.01, 0.005),
        object_id=passes["Object Index"],
        adaptive=True,
    )
    counts = sample_counts(**kw)
    assert counts.max() == 32 and 0 < counts[counts > 0].min() < 32  # the plan varies here
    burley(**kw, energy="lambert")
    combined(
        **kw,
        normal=passes["Normal"],
        position=passes["Position"],
        thickness=passes["Thickness"],
        lights=scene.lights,
        thickness_distance_su=0.05,
        energy="lambert",
    )


def test_the_same_result_on_one_and_two_threads():
    kw, _ = _inputs("edge", 40.0)
    before = numba.get_num_threads()
    with backend.use("numba"):
        try:
            numba.set_num_threads(1)
            one = burley(**kw, seed=5)
            numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
            two = burley(**kw, seed=5)
        finally:
            numba.set_num_threads(before)
        again = burley(**kw, seed=5)
    assert np.array_equal(one, two)
    assert np.array_equal(one, again)


@pytest.mark.parametrize("n_samples", (32, 128))
@pytest.mark.parametrize("kind", ("edge", "smooth"))
@pytest.mark.parametrize("footprint_px", (10.0, 40.0))
def test_adaptive_is_within_its_bound_of_twice_the_fixed_samples(kind, footprint_px, n_samples):
    """Where a pixel takes the most samples (n) its spiral is the fixed one's: the same result to
    the bit (without the clean-up, which mixes in neighbours). Where it takes fewer, the plan
    estimated its relative standard error below its target t = ``ERROR`` x sqrt(32 / n) at that
    count; 2n fixed samples have at most sqrt(m / 2n) t there (m: the ladder's count below n, the
    most the variation asked for; 2n divide that variance by 2n instead of m); the two errors are
    independent, so their difference has an RMS of at most sqrt(1 + m / 2n) t: 1.17 ``ERROR`` at
    32 (m = 23, against 64 fixed samples), 0.58 ``ERROR`` at 128 (m = 91, against 256)."""
    kw, _ = _inputs(kind, footprint_px)
    kw["energy"] = "lambert"
    kw["n_samples"] = n_samples
    counts = sample_counts(**kw)
    fixed2n = burley(**{**kw, "adaptive": False, "n_samples": 2 * n_samples}, smooth_px=0)
    fixed = burley(**{**kw, "adaptive": False}, smooth_px=0)
    ours = burley(**kw, smooth_px=0)
    most = counts == n_samples
    assert np.array_equal(ours[most], fixed[most])
    fewer = ~most
    assert fewer.any()
    rel = (ours[fewer] - fixed2n[fewer]) / fixed2n[fewer]
    rms = float(np.sqrt(np.mean(rel**2)))
    below = int(adaptive.ladder(n_samples)[-2])
    target = adaptive.ERROR * math.sqrt(32 / n_samples)
    assert rms <= math.sqrt(1 + below / (2 * n_samples)) * target, rms
