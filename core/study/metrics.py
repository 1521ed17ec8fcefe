"""Error metrics of a technique's image against the Cycles random-walk reference.

Definitions (also printed in every report, docs/references.md §8):

- ``rmse``: root mean square difference over the masked pixels and the three colour channels,
  on linear scene-referred RGB, after an optional ``box``×``box`` mean downsampling of both
  images (it divides the Monte Carlo noise of the reference by about ``box`` while keeping the
  smooth SSS differences; a block counts as masked when all of its pixels are).
- ``rel_rmse``: ``rmse`` divided by the mean reference value over the same pixels.
- ``ssim``: structural similarity (Wang et al. 2004; 7×7 Gaussian window, sigma 1.5, K1 0.01,
  K2 0.03, dynamic range 1) of the luminance after the tone map ``tonemap`` (Reinhard x/(1+x)
  then the sRGB transfer curve), averaged over the masked pixels. 1 is identical.

Pixels where either image is not finite are left out and counted in ``nonfinite``.

``split_error`` splits a technique's error into **bias** (what stays with noise-free passes) and
**pass noise** (what the Monte Carlo noise of its input passes adds), from the errors measured
with passes at two sample counts.
"""

from __future__ import annotations

import math

import numpy as np

#: Rec. 709 luminance weights (linear RGB).
LUMA = np.array([0.2126, 0.7152, 0.0722], dtype=np.float64)


def _check(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None):
    a = np.asarray(image, dtype=np.float64)
    b = np.asarray(reference, dtype=np.float64)
    if a.ndim != 3 or a.shape[2] < 3:
        raise ValueError(f"image: expected shape (H, W, 3 or 4), got {a.shape}")
    if b.shape[:2] != a.shape[:2] or b.ndim != 3 or b.shape[2] < 3:
        raise ValueError(f"reference: expected shape {a.shape[:2] + (3,)}, got {b.shape}")
    a, b = a[..., :3], b[..., :3]
    if mask is None:
        m = np.ones(a.shape[:2], dtype=bool)
    else:
        m = np.asarray(mask, dtype=bool)
        if m.shape != a.shape[:2]:
            raise ValueError(f"mask: expected shape {a.shape[:2]}, got {m.shape}")
    return a, b, m


def box_downsample(image: np.ndarray, box: int) -> np.ndarray:
    """Mean over ``box``×``box`` blocks (the image is cropped to a multiple of ``box``)."""
    if not isinstance(box, int) or box < 1:
        raise ValueError(f"box: expected an integer >= 1, got {box!r}")
    if box == 1:
        return image
    h, w = image.shape[0] // box * box, image.shape[1] // box * box
    if h == 0 or w == 0:
        raise ValueError(f"box: {box} is larger than the image ({image.shape[0]}x{image.shape[1]})")
    x = image[:h, :w]
    return x.reshape(h // box, box, w // box, box, *x.shape[2:]).mean(axis=(1, 3))


def tonemap(image: np.ndarray) -> np.ndarray:
    """Reinhard x/(1+x) on linear RGB, then the sRGB transfer curve: display values in [0, 1]."""
    x = np.clip(np.asarray(image, dtype=np.float64), 0.0, None)
    x = x / (1.0 + x)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def _gaussian_filter(x: np.ndarray, sigma: float = 1.5, radius: int = 3) -> np.ndarray:
    t = np.arange(-radius, radius + 1, dtype=np.float64)
    g = np.exp(-0.5 * (t / sigma) ** 2)
    g /= g.sum()
    pad = np.pad(x, radius, mode="reflect") if min(x.shape) > radius else np.pad(x, radius, mode="edge")
    rows = sum(g[i] * pad[:, i : i + x.shape[1]] for i in range(2 * radius + 1))
    return sum(g[i] * rows[i : i + x.shape[0], :] for i in range(2 * radius + 1))


def ssim_map(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel SSIM of two single-channel images with values in [0, 1]."""
    c1, c2 = (0.01) ** 2, (0.03) ** 2
    mu_a, mu_b = _gaussian_filter(a), _gaussian_filter(b)
    var_a = _gaussian_filter(a * a) - mu_a**2
    var_b = _gaussian_filter(b * b) - mu_b**2
    cov = _gaussian_filter(a * b) - mu_a * mu_b
    return ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / ((mu_a**2 + mu_b**2 + c1) * (var_a + var_b + c2))


def compare_images(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None, *, box: int = 1) -> dict:
    """The metrics of the module docstring, as a plain dict (JSON-ready)."""
    a, b, m = _check(image, reference, mask)
    finite = np.isfinite(a).all(axis=2) & np.isfinite(b).all(axis=2)
    nonfinite = int(np.count_nonzero(m & ~finite))
    m = m & finite
    a = np.where(finite[..., None], a, 0.0)
    b = np.where(finite[..., None], b, 0.0)
    luma_ssim = ssim_map(tonemap(a) @ LUMA, tonemap(b) @ LUMA)
    if box > 1:
        a, b = box_downsample(a, box), box_downsample(b, box)
        m = box_downsample(m.astype(np.float64), box) >= 1.0
    count = int(np.count_nonzero(m))
    if count == 0:
        return {"pixels": 0, "nonfinite": nonfinite, "rmse": None, "rel_rmse": None, "ssim": None, "box": box}
    diff = a[m] - b[m]
    rmse = float(np.sqrt(np.mean(diff**2)))
    ref_mean = float(np.mean(b[m]))
    full_mask = mask if mask is not None else np.ones(image.shape[:2], dtype=bool)
    ssim_pixels = np.asarray(full_mask, dtype=bool) & finite
    return {
        "pixels": count,
        "nonfinite": nonfinite,
        "rmse": rmse,
        "rel_rmse": rmse / ref_mean if ref_mean > 0 else None,
        "ssim": float(np.mean(luma_ssim[ssim_pixels])),
        "box": box,
    }


def split_error(error: float, error_high: float, samples: int, samples_high: int) -> tuple[float, float]:
    """(bias, pass noise) of a technique whose error is ``error`` with passes of ``samples``
    samples and ``error_high`` with passes of ``samples_high`` (> ``samples``) samples.

    Independent errors add in quadrature, and the passes' noise variance falls as 1 / samples
    (Monte Carlo), so error² = bias² + noise² and error_high² = bias² + noise² · samples /
    samples_high; hence noise² = (error² − error_high²) / (1 − samples / samples_high) and
    bias² = error² − noise², each clipped to [0, error²] (the reference's own noise stays in the
    bias; with a noisy reference error_high can exceed error, and then all of it is bias).
    """
    if not (isinstance(samples, int) and isinstance(samples_high, int) and 0 < samples < samples_high):
        raise ValueError(f"samples: expected 0 < samples < samples_high, got {samples!r} and {samples_high!r}")
    noise2 = max(error**2 - error_high**2, 0.0) / (1.0 - samples / samples_high)
    noise2 = min(noise2, error**2)
    return math.sqrt(error**2 - noise2), math.sqrt(noise2)


def split_seeds(image: np.ndarray, other: np.ndarray, reference: np.ndarray, mask=None, *, box: int = 1):
    """(bias, noise) of ``image``'s rel_rmse against ``reference``, from ``other``: the same render
    at another seed (a denoised Cycles image, whose error is not Monte Carlo noise alone). The two
    differ by their noise only, so one image's noise is the difference over sqrt 2, measured like
    rel_rmse; bias² = rel_rmse² − noise², clipped to [0, rel_rmse²] (the reference's own noise stays
    in the bias, as in ``split_error``). (None, None) where nothing could be measured."""
    error = compare_images(image, reference, mask, box=box)["rel_rmse"]
    a = np.asarray(image, np.float64)[..., :3]
    b = np.asarray(other, np.float64)[..., :3]
    ref = np.asarray(reference, np.float64)[..., :3]
    noise = compare_images(ref + (a - b) / math.sqrt(2.0), ref, mask, box=box)["rel_rmse"]
    if error is None or noise is None:
        return None, None
    noise = min(noise, error)
    return math.sqrt(error**2 - noise**2), noise


def error_map(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per-pixel relative error |a - b| / (mean(b) + eps) of the luminance, float32 (H, W)."""
    a, b, _ = _check(image, reference, None)
    la, lb = np.nan_to_num(a @ LUMA), np.nan_to_num(b @ LUMA)
    scale = max(float(np.mean(np.abs(lb))), 1e-12)
    return (np.abs(la - lb) / scale).astype(np.float32)
