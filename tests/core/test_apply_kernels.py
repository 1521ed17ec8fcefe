"""``core.pipeline.apply``'s compiled compositing and ``core.scene.extent.group_extents``' split by comparisons
give the same bits as their NumPy code, also on the values that take the other branches: results
that are NaN, infinite or overflow with the gain, a fitted gain, channels left unchanged, -0 in
Combined; labels too many or too spread for comparisons."""

import numpy as np
import pytest

from sss_lab.core.compute import backend
from sss_lab.core.pipeline import apply as core_apply
from sss_lab.core.scene.extent import group_extents

needs_numba = pytest.mark.skipif(backend.compiled() is None, reason="Numba cannot load")


def _case(held: bool, gain, unchanged, h=48, w=40):
    rng = np.random.default_rng(3)
    image = rng.normal(size=(h, w, 4)).astype(np.float32)
    image[1, 1, :3] = -0.0
    sss = np.zeros((h, w, 3), np.float32)
    out = rng.normal(size=(h, w, 3)).astype(np.float32)
    out[2, 3] = (np.nan, 1.0, 1.0)
    out[4, 5] = (1.0, np.inf, 1.0)
    out[6, 7] = (1.0, 1.0, -np.inf)
    out[8, 9] = 3e38  # overflows with a gain above 1
    out[1, 1] = (0.0, -0.0, 0.0)
    mask = rng.random((h, w)) < 0.6
    mask[[1, 2, 4, 6, 8], [1, 3, 5, 7, 9]] = True
    mask[:, -3:] = False
    original = None
    if held:
        original = (rng.random((h, w, 3)).astype(np.float32), rng.normal(size=(h, w, 3)).astype(np.float32))
        original[1][1, 1] = 0.0
    return image, sss, out, gain, original, mask, unchanged


@needs_numba
@pytest.mark.parametrize("held", [False, True], ids=["adds light", "scatters"])
@pytest.mark.parametrize("gain", [None, (1.5, 1.0, 0.25), 2.0], ids=["no gain", "gain per channel", "one gain"])
@pytest.mark.parametrize("unchanged", [(), (0, 2)], ids=["all channels", "R and B unchanged"])
def test_composite_equals_its_numpy_code_to_the_bit(held, gain, unchanged):
    image, sss, out, gain, original, mask, unchanged = _case(held, gain, unchanged)
    expected_image, expected_sss = image.copy(), sss.copy()
    with np.errstate(over="ignore"):  # the gain's product overflows on one pixel
        expected = core_apply._composite_numpy(expected_image, expected_sss, out, gain, original, mask, unchanged)
    assert expected[0] >= 3  # the NaN and the infinities on the mask are counted, and left as they were
    # Random terms turn some non-negative Combined values negative: clamped to 0, and counted.
    assert expected[1] > 0
    with backend.use("numba"):
        got = core_apply._composite(image, sss, out, gain, original, mask, unchanged)
    assert got == expected
    assert image.tobytes() == expected_image.tobytes() and sss.tobytes() == expected_sss.tobytes()
    assert (sss[mask] != 0).any() and not sss[~mask].any()


def _groups_by_sorting(ok, scale, labels):
    """group_extents' groups the way it always can: the pixels sorted by label."""
    flat = np.flatnonzero(ok)
    lab = np.rint(np.asarray(labels, np.float64).ravel()[flat]).astype(np.int64)
    order = np.argsort(lab, kind="stable")
    groups = np.split(flat[order], np.flatnonzero(np.diff(lab[order])) + 1)
    return [np.sort(g) for g in groups]


@pytest.mark.parametrize("labels", ["one", "few", "many", "wide"])
def test_group_extents_splits_by_label_as_sorting_does(labels):
    rng = np.random.default_rng(4)
    h, w = 60, 70
    ok = rng.random((h, w)) < 0.5
    ids = {
        "one": np.full((h, w), 3.0),
        "few": rng.integers(0, 5, (h, w)) + rng.choice([-0.4, 0.0, 0.4], (h, w)),
        "many": rng.integers(-20, 20, (h, w)).astype(np.float64),  # more labels than one comparison each
        "wide": rng.choice([0.0, 1e6, 2.5], (h, w)),  # 2.5 rounds to 2 (half to even)
    }[labels].astype(np.float32)
    scale = rng.uniform(10.0, 50.0, (h, w)).astype(np.float32)
    got = group_extents(ok, scale, ids)
    got_lazy = group_extents(ok, lambda idx: scale.ravel()[idx], ids)
    expected = _groups_by_sorting(ok, scale, ids)
    assert len(got) == len(expected) == len(got_lazy)
    for (idx, extent), (idx_lazy, extent_lazy), want in zip(got, got_lazy, expected, strict=True):
        np.testing.assert_array_equal(idx, want)
        np.testing.assert_array_equal(idx_lazy, want)
        ys, xs = np.divmod(want, w)
        diag = np.hypot(float(xs.max() - xs.min()), float(ys.max() - ys.min())) + 1.0
        assert extent == extent_lazy == diag / float(scale.ravel()[want].astype(np.float64).min())


@pytest.mark.parametrize("listed", [(1, 2), (1, 2, 16777216, 16777218, 1 << 40)], ids=["small", "beyond float32"])
def test_plan_finds_each_index_as_the_int64_map_does(listed):
    """``plan`` compares the pass rounded as float32 for indices below 2^24 and the int64 map
    (``index_map``) for the others: the same pixels and unlisted indices as the int64 map alone,
    with NaN, +-inf and values beyond int64 in the pass."""
    from dataclasses import replace

    from sss_lab.core.pipeline.plan import index_map, plan
    from sss_lab.core.scene.exr import Passes
    from sss_lab.core.study.synthetic import sphere_scene

    arrays, scene = sphere_scene(48, 32)
    mi = arrays["Material Index"].copy()
    mi[0, :6] = [np.nan, np.inf, -np.inf, 1e20, -1e20, 2.5]  # 2.5 rounds to 2 (half to even)
    mi[1, :4] = [16777216.0, 16777218.0, 7.0, float(1 << 40)]
    base = scene.materials[0]
    materials = list(scene.materials) + [replace(base, index=k) for k in listed if k > 2]
    scene = replace(scene, materials=materials)
    passes = Passes({**arrays, "Material Index": mi})
    with np.errstate(invalid="ignore"):
        p = plan(passes, scene, "burley")
        index = index_map(passes)
    for mp in p.materials:
        assert mp.pixels == (int(np.count_nonzero(index == mp.material.index)) if mp.material.index > 0 else 0)
    known = {m.index for m in materials}
    values, counts = np.unique(index[index > 0], return_counts=True)
    expected = {int(v): int(c) for v, c in zip(values, counts, strict=True) if int(v) not in known}
    assert p.unknown_indices == expected and 7 in expected
    assert {mp.material.index: mp.pixels for mp in p.materials}.get(16777216, 1) == 1


@pytest.mark.parametrize("n", [1, 2, 3, 4, 10, 11, 1000, 1001, 65536])
def test_median_equals_numpy_median(n):
    """``_arrays.median`` (one selection) gives ``np.median``'s float, ties and spreads alike."""
    from sss_lab.core.base import arrays as _arrays

    rng = np.random.default_rng(n)
    for scale in (1.0, 1e-30, 3e38):
        for ties in (False, True):
            z = (rng.random(n) * scale).astype(np.float32)
            if ties:
                z = np.round(z / np.float32(scale) * 4) * np.float32(scale / 4)
            with np.errstate(over="ignore"):  # the mean of two values near 3e38 is inf in both
                expected = float(np.median(z))
                assert _arrays.median(z.copy()) == expected
