"""Metrics and PNG output: closed-form cases."""

import struct
import zlib

import numpy as np
import pytest

from sss_lab.core.study.metrics import box_downsample, compare_images, error_map, ssim_map, tonemap
from sss_lab.core.study.png import encode_png, grid, heat, to_display


def test_rmse_of_a_constant_offset_is_the_offset():
    ref = np.full((8, 8, 3), 0.5)
    m = compare_images(ref + 0.1, ref)
    assert m["rmse"] == pytest.approx(0.1, rel=1e-12)
    assert m["rel_rmse"] == pytest.approx(0.2, rel=1e-12)
    assert m["pixels"] == 64


def test_identical_images_have_ssim_one_and_zero_error():
    rng = np.random.default_rng(1)
    ref = rng.random((16, 16, 3))
    m = compare_images(ref, ref)
    assert m["rmse"] == 0.0
    assert m["ssim"] == pytest.approx(1.0, abs=1e-12)


def test_ssim_drops_for_structure_changes():
    rng = np.random.default_rng(2)
    a = rng.random((32, 32))
    assert np.mean(ssim_map(a, a[::-1])) < 0.5


def test_mask_limits_the_pixels():
    ref = np.zeros((4, 4, 3))
    img = ref.copy()
    img[0, 0] = 1.0  # outside the mask: must not count
    mask = np.zeros((4, 4), dtype=bool)
    mask[2:, 2:] = True
    m = compare_images(img, ref, mask)
    assert m["pixels"] == 4 and m["rmse"] == 0.0


def test_box_downsampling_divides_independent_noise_by_the_box_size():
    # Zero-mean i.i.d. noise: the mean of k*k samples has standard deviation sigma / k.
    rng = np.random.default_rng(3)
    ref = np.ones((256, 256, 3))
    noisy = ref + rng.normal(0.0, 0.1, ref.shape)
    r1 = compare_images(noisy, ref)["rmse"]
    r4 = compare_images(noisy, ref, box=4)["rmse"]
    # 256*256*3/16 = 12288 samples: the sample rmse is within ~1 % of sigma/4 (1/sqrt(2n) ~ 0.6 %).
    assert r4 == pytest.approx(r1 / 4, rel=0.03)


def test_nonfinite_pixels_are_left_out_and_counted():
    ref = np.ones((4, 4, 3))
    img = ref.copy()
    img[1, 1, 0] = np.nan
    img[2, 2, 1] = np.inf
    m = compare_images(img, ref)
    assert m["nonfinite"] == 2 and m["pixels"] == 14 and m["rmse"] == 0.0


def test_empty_mask_gives_no_numbers():
    m = compare_images(np.ones((2, 2, 3)), np.ones((2, 2, 3)), np.zeros((2, 2), bool))
    assert m["pixels"] == 0 and m["rmse"] is None


def test_bad_shapes_are_named():
    with pytest.raises(ValueError, match="reference"):
        compare_images(np.ones((2, 2, 3)), np.ones((3, 2, 3)))
    with pytest.raises(ValueError, match="mask"):
        compare_images(np.ones((2, 2, 3)), np.ones((2, 2, 3)), np.ones((3, 3), bool))
    with pytest.raises(ValueError, match="box"):
        box_downsample(np.ones((2, 2)), 0)


def test_tonemap_is_monotone_and_bounded():
    x = np.array([0.0, 0.001, 0.5, 1.0, 10.0, 1e6])
    y = tonemap(x)
    assert y[0] == 0.0 and np.all(np.diff(y) > 0) and y[-1] <= 1.0
    # Reinhard(1) = 0.5; sRGB(0.5) = 1.055 * 0.5**(1/2.4) - 0.055 = 0.7354
    assert y[3] == pytest.approx(0.7354, abs=1e-4)


def test_error_map_is_relative_to_the_mean():
    ref = np.full((2, 2, 3), 2.0)
    img = ref.copy()
    img[0, 0] = 3.0
    e = error_map(img, ref)
    assert e[0, 0] == pytest.approx(0.5) and e[1, 1] == 0.0


def _decode_png(data: bytes) -> np.ndarray:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, {}
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF
        chunks[kind] = chunks.get(kind, b"") + body
        pos += 12 + length
    w, h, depth, colour = struct.unpack(">IIBB", chunks[b"IHDR"][:10])
    assert (depth, colour) == (8, 2)
    raw = np.frombuffer(zlib.decompress(chunks[b"IDAT"]), dtype=np.uint8).reshape(h, 1 + 3 * w)
    assert np.all(raw[:, 0] == 0)  # filter type None on every row
    return raw[:, 1:].reshape(h, w, 3)


def test_png_round_trip():
    rng = np.random.default_rng(4)
    img = rng.integers(0, 256, (5, 7, 3), dtype=np.uint8)
    np.testing.assert_array_equal(_decode_png(encode_png(img)), img)


def test_display_marks_nan_magenta_and_keeps_hdr_below_white():
    lin = np.array([[[np.nan, 0, 0], [1e5, 1e5, 1e5], [0, 0, 0]]])
    d = to_display(lin)
    assert tuple(d[0, 0]) == (255, 0, 255) and tuple(d[0, 2]) == (0, 0, 0) and d[0, 1, 0] == 255


def test_heat_and_grid():
    h = heat(np.array([[0.0, 1.0, 2.0]]), vmax=1.0)
    assert tuple(h[0, 0]) == (0, 0, 0) and tuple(h[0, 1]) == (255, 255, 255) and tuple(h[0, 2]) == (255, 255, 255)
    g = grid([np.zeros((2, 3, 3), np.uint8)] * 3, columns=2, gap=1)
    assert g.shape == (5, 7, 3)
    with pytest.raises(ValueError, match="encode_png"):
        encode_png(np.zeros((2, 2, 3), np.float32))


def test_split_error_recovers_bias_and_pass_noise():
    import math

    from sss_lab.core.study.metrics import split_error

    # Errors built from a known bias and a pass noise whose variance falls as 1 / samples.
    bias, noise = 0.08, 0.05
    error = math.hypot(bias, noise)
    error_high = math.sqrt(bias**2 + noise**2 * 64 / 256)
    b, n = split_error(error, error_high, 64, 256)
    assert math.isclose(b, bias, rel_tol=1e-9) and math.isclose(n, noise, rel_tol=1e-9)
    # A noisy reference can make the high-sample error larger: all of it is then bias.
    assert split_error(0.1, 0.11, 64, 256) == (0.1, 0.0)
    with pytest.raises(ValueError, match="samples"):
        split_error(0.1, 0.1, 256, 64)


def test_split_seeds_recovers_a_denoisers_bias_and_its_noise():
    """Two renders at two seeds share their bias and differ in their noise: a 5 % brighter image
    with independent noise of 3 % of the mean reads back bias 5 % and noise 3 %."""
    from sss_lab.core.study.metrics import split_seeds

    rng = np.random.default_rng(7)
    ref = np.full((256, 256, 3), 0.5)
    a = ref * 1.05 + rng.normal(0, 0.015, ref.shape)
    b = ref * 1.05 + rng.normal(0, 0.015, ref.shape)
    bias, noise = split_seeds(a, b, ref)
    # 196 608 values each: the estimates' sampling spread is a fraction of a percent; 3 % is room.
    assert bias == pytest.approx(0.05, rel=0.03) and noise == pytest.approx(0.03, rel=0.03)
    assert split_seeds(ref, ref, ref) == (0.0, 0.0)
