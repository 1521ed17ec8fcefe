"""``core.apply``'s compiled compositing and ``core.extent.group_extents``' split by comparisons
give the same bits as their NumPy code, also on the values that take the other branches: results
that are NaN, infinite or overflow with the gain, a fitted gain, channels left unchanged, -0 in
Combined; labels too many or too spread for comparisons."""

import numpy as np
import pytest

from sss_lab.core import apply as core_apply
from sss_lab.core import backend
from sss_lab.core.extent import group_extents

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
    assert expected >= 3  # the NaN and the infinities on the mask are counted, and left as they were
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
