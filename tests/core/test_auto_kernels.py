"""core/pipeline/auto.py's feature loops on the compiled backend (``core/pipeline/_kernels.py``: ``block_means``,
``blurred_change``, ``index_box``, ``index_window``).

The core tests run in ``core.compute.backend``'s check mode: every call below runs the kernel and the NumPy
reference and raises ``BackendMismatch`` unless they are equal to the bit. The expected values here
come from independent computations (naive loops, NumPy's own ``rint`` and ``isfinite``), on inputs
chosen for the cases the kernels treat apart: NaN and infinities, indices half-way between two
integers, windows at the frame's edges."""

import numpy as np
import pytest

from sss_lab.core.compute import backend
from sss_lab.core.pipeline import auto
from sss_lab.core.scene.exr import Passes
from sss_lab.core.scene.scene import Camera, SceneDescription

pytestmark = pytest.mark.skipif(backend.compiled() is None, reason="Numba is not available")


def test_box_means_of_a_channel_match_a_naive_loop():
    """The diffusion's box mean inside the mask minus the value, float32. Tolerance: the kernel
    sums the masked values in float32 (as the reference, whose summed-area table is NumPy's
    float32 cumulative sum of a float32 array): each entry of the table, at most H W for values
    below 1, is made by at most H + W additions, each within 2^-24 of that; a box's sum reads four
    entries, and its mean divides it by at least 1."""
    rng = np.random.default_rng(11)
    h, w, half = 19, 23, 3
    e = rng.random((h, w)).astype(np.float32)
    mask = rng.random((h, w)) < 0.6
    mask[:, 0] = False  # a column without a pixel of the mask
    got = auto._blurred_change(e, mask, half)
    assert got.dtype == np.float32 and got.shape == (h, w)
    bound = 4 * (h + w) * 2.0**-24 * (h * w)
    for y in range(h):
        for x in range(w):
            ys, xs = slice(max(y - half, 0), y + half + 1), slice(max(x - half, 0), x + half + 1)
            m = mask[ys, xs]
            mean = e[ys, xs][m].astype(np.float64).mean() if m.any() else float(e[y, x])
            assert got[y, x] == pytest.approx(mean - float(e[y, x]), abs=bound)


def _shared(index: np.ndarray, combined: np.ndarray) -> auto._Shared:
    h, w = index.shape
    rgba = np.concatenate([combined, np.ones((h, w, 1), np.float32)], axis=2)
    passes = Passes({"Combined": rgba, "Diffuse Color": np.ones((h, w, 3), np.float32), "Material Index": index})
    camera = Camera(width_px=w, height_px=h)
    return auto._Shared(passes, SceneDescription(camera=camera, lights=(), materials=()))


def test_a_materials_window_and_pixels_as_the_index_rounds():
    """The Material Index pass rounds half to even (``np.rint``): 1.5 and 2.5 are index 2, 0.5 is
    0; NaN and infinities are no index. The window starts on even rows and columns; its pixels
    are those of the index whose three Combined values are finite."""
    h, w = 12, 15
    index = np.zeros((h, w), np.float32)
    index[3, 5] = 1.5
    index[9, 12] = 2.5
    index[4, 6] = 2.0
    index[5, 7] = 2.49
    index[6, 8] = 3.5  # 4
    index[0, 0] = np.nan
    index[0, 1] = np.inf
    index[1, 0] = -np.inf
    index[2, 2] = 0.5  # 0
    combined = np.ones((h, w, 3), np.float32)
    combined[4, 6, 1] = np.nan  # index 2, not finite: not a pixel of the window
    combined[7, 7, 2] = np.inf  # not index 2: does not matter
    sh = _shared(index, combined)
    win, mask = auto._window(sh, 2)
    expected_on = np.rint(index) == 2.0
    rows, cols = np.flatnonzero(expected_on.any(axis=1)), np.flatnonzero(expected_on.any(axis=0))
    assert (rows[0], rows[-1], cols[0], cols[-1]) == (3, 9, 5, 12)
    assert win == (slice(2, 10), slice(4, 13))  # starts rounded down to even
    expected = (expected_on & np.isfinite(combined).all(axis=2))[win]
    assert np.array_equal(mask, expected) and mask.sum() == 3
    assert auto._window(sh, 7) is None
    win0, mask0 = auto._window(sh, 0)  # values in [-0.5, 0.5]; not NaN, not the infinities
    assert win0 == (slice(0, h), slice(0, w))
    assert np.array_equal(mask0, (np.rint(index) == 0.0) & np.isfinite(combined).all(axis=2))
    assert not mask0[0, 0] and not mask0[0, 1] and not mask0[1, 0] and mask0[2, 2] and not mask0[7, 7]


def test_the_check_mode_catches_a_kernel_that_differs(monkeypatch):
    """The comparison with the reference can fail: a block-means kernel off by one unit in the
    last place in one value is refused."""
    kernels = backend.kernels("sss_lab.core.pipeline")
    true_kernel = kernels.block_means

    def off_by_one_ulp(a, size, part, count, out):
        true_kernel(a, size, part, count, out)
        out[0, 0, 0] = np.nextafter(out[0, 0, 0], np.float32(np.inf))

    monkeypatch.setattr(kernels, "block_means", off_by_one_ulp)
    a = np.random.default_rng(2).random((8, 8, 3)).astype(np.float32)
    with backend.use("check"), pytest.raises(backend.BackendMismatch, match="auto block means"):
        auto._block_means(a, 4)
    with backend.use("numpy"):  # the reference alone does not call the kernel
        auto._block_means(a, 4)
