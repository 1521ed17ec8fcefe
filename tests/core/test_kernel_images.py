"""core/optics/kernel_images.py: the kernel images of the compositor node groups (no Blender)."""

import math

import numpy as np
import pytest

from sss_lab.core.optics.kernel_images import (
    MAX_RADIUS_PX,
    burley_kernel_image,
    correlate_zero,
    separable_kernel_image,
)
from sss_lab.core.optics.kernels import make_kernel
from sss_lab.core.optics.profiles import TRUNCATION, burley_radial_pdf
from sss_lab.core.techniques.ssss.technique import filter_1d


@pytest.mark.parametrize("kernel_type,n_taps", [("preintegrated", 17), ("artist", 25), ("preintegrated", 11)])
def test_separable_image_is_core_ssss_pass_at_a_fixed_scale(kernel_type, n_taps):
    kernel = make_kernel(kernel_type, n_taps, d_su=(0.02, 0.01, 0.005))
    scale = 30.0
    line = separable_kernel_image(kernel, scale)
    r = line.shape[0] // 2
    assert line.shape == (2 * r + 1, 3) and r == math.ceil(kernel.radius_su * scale)
    np.testing.assert_allclose(line.sum(axis=0), 1.0, atol=1e-6)
    np.testing.assert_allclose(line, line[::-1], atol=1e-7)  # the offsets are symmetric
    image = np.random.default_rng(0).uniform(0, 1, (24, 64, 3)).astype(np.float32)
    # Rows: the horizontal pass; away from the border both read the same pixels.
    want = filter_1d(image, offsets_px=kernel.offsets_su * scale, weights=kernel.weights, axis=1)
    got = correlate_zero(image, line[None, :, :])
    np.testing.assert_allclose(got[:, r:-r], want[:, r:-r], atol=2e-6)
    # Columns: the vertical pass.
    image_t = np.ascontiguousarray(image.transpose(1, 0, 2))
    want = filter_1d(image_t, offsets_px=kernel.offsets_su * scale, weights=kernel.weights, axis=0)
    got = correlate_zero(image_t, line[:, None, :])
    np.testing.assert_allclose(got[r:-r], want[r:-r], atol=2e-6)


def test_separable_image_under_half_a_pixel_is_the_identity():
    kernel = make_kernel("preintegrated", 17, d_su=(0.001, 0.001, 0.001))
    assert kernel.radius_su * 20.0 <= 0.5
    np.testing.assert_array_equal(separable_kernel_image(kernel, 20.0), np.ones((1, 3), np.float32))


def _truncated_r2(d_px: float, cut: float) -> float:
    """E[r^2] of the profile truncated at ``cut`` (fine quadrature of the radial pdf), in px^2."""
    r = (np.arange(200000) + 0.5) / 200000 * cut
    pdf = burley_radial_pdf(r, d_px)
    return float((r * r * pdf).sum() / pdf.sum())


def test_burley_image_is_the_truncated_profile_per_channel():
    d_su, scale = (0.5, 0.3, 0.2), 10.0  # d = 5, 3, 2 px; every channel ends at 16 d_max = 80 px
    k = burley_kernel_image(d_su, scale).astype(np.float64)
    r = k.shape[0] // 2
    assert k.shape == (2 * r + 1, 2 * r + 1, 3) and r == math.ceil(TRUNCATION * 5.0)
    np.testing.assert_allclose(k.sum(axis=(0, 1)), 1.0, atol=1e-6)
    np.testing.assert_array_equal(k, k[::-1])
    np.testing.assert_array_equal(k, k.transpose(1, 0, 2))
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
    for c in range(3):
        d_px = d_su[c] * scale
        got = float((k[..., c] * (dx * dx + dy * dy)).sum())
        # A pixel's mass sits at its centre: the squared radius loses the square's own 1/6 (exact
        # for a profile that is smooth over a pixel; 1e-2 covers d down to 2 px).
        assert got == pytest.approx(_truncated_r2(d_px, TRUNCATION * 5.0) - 1.0 / 6.0, rel=1e-2)
    # Nothing beyond the truncation circle (the corners of the square image stay empty).
    assert k[0, 0].max() == 0.0


def test_burley_image_identity_cases():
    np.testing.assert_array_equal(burley_kernel_image((0.01, 0.01, 0.01), 5.0), np.ones((1, 1, 3), np.float32))
    k = burley_kernel_image((0.5, 0.0, 0.001), 10.0)  # G: d = 0; B: 16 d = 0.16 px
    centre = k.shape[0] // 2
    for c in (1, 2):
        assert k[centre, centre, c] == 1.0 and k[..., c].sum() == 1.0


def test_bad_input_is_refused():
    kernel = make_kernel("preintegrated", 17, d_su=(0.02, 0.01, 0.005))
    with pytest.raises(ValueError, match="pixels_per_unit"):
        separable_kernel_image(kernel, 0.0)
    with pytest.raises(ValueError, match="pixels_per_unit"):
        burley_kernel_image((0.1, 0.1, 0.1), float("nan"))
    with pytest.raises(ValueError, match="d_su"):
        burley_kernel_image((0.1, -0.1, 0.1), 10.0)
    with pytest.raises(ValueError, match="kernel"):
        separable_kernel_image("not a kernel", 10.0)
    with pytest.raises(ValueError, match="pixels wide"):
        burley_kernel_image((1.0, 1.0, 1.0), MAX_RADIUS_PX)


def test_correlate_zero_gathers_with_zero_borders():
    image = np.zeros((5, 7, 1))
    image[2, 3] = 1.0
    kernel = np.zeros((3, 3, 1))
    kernel[1, 2] = 1.0  # take the pixel to the right
    out = correlate_zero(image, kernel)
    assert out[2, 2, 0] == 1.0 and out.sum() == 1.0
    edge = correlate_zero(np.ones((5, 7, 1)), kernel)
    assert edge[:, -1, 0].max() == 0.0 and edge[:, :-1, 0].min() == 1.0
    with pytest.raises(ValueError, match="odd"):
        correlate_zero(image, np.ones((2, 3, 1)))
