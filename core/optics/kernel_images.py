"""Kernel images for Blender's Convolve compositor node, rasterized at a fixed pixel scale (no Blender).

The compositor node groups (``nodes/``) convolve with images computed here. The Convolve node's
conventions, measured with bpy 5.2.3 (docs/compositor.md, "Convolve node"):

- it gathers: output(p) = sum_o K[c + o] * input(p + o), with o the offset from the output
  pixel (rows and columns in the same orientation as the image) and c the kernel's centre pixel,
  at index size // 2 of each axis when rows count from the bottom (Blender's order); an odd size
  puts the centre in the middle either way, so every kernel here has an odd size;
- a Color kernel convolves each channel with its own kernel channel (R with R, ...);
- pixels outside the image count as zero (no clamping, no renormalization at the borders);
- "Normalize Kernel" divides by the kernel's sum; the builders switch it off, since the
  kernels here already sum to one per channel.

Arrays here are (rows, columns[, 3]) with row 0 at the top, like every image of ``core``;
``nodes/`` flips them to Blender's bottom-to-top order when it writes the image.

- ``separable_kernel_image``: the 1-D kernel of ``core.techniques.ssss.technique`` at a fixed pixels-per-unit. Each
  tap at s * offset pixels is split between its two neighbouring pixels by linear interpolation,
  exactly as ``core.techniques.ssss.technique`` reads it, so on a constant-depth surface the two give the same
  result away from the image border.
- ``burley_kernel_image``: the Burley profile of ``core.techniques.burley.technique`` integrated over each pixel's
  square, truncated at 16 d of the widest channel, normalized per channel. This is what
  ``core.techniques.burley.technique`` converges to with many samples on a constant-depth surface: it point-samples
  the pixel whose square holds each sample, so a pixel gathers the profile's mass over its
  square.
"""

from __future__ import annotations

import math

import numpy as np

from .kernels import SeparableKernel
from .profiles import TRUNCATION

#: Largest kernel radius in pixels (a 2049-pixel-wide kernel image); wider kernels are refused.
MAX_RADIUS_PX = 1024


def _scale(pixels_per_unit) -> float:
    try:
        s = float(pixels_per_unit)
    except (TypeError, ValueError):
        raise ValueError(f"pixels_per_unit: expected a number > 0, got {pixels_per_unit!r}") from None
    if not (math.isfinite(s) and s > 0):
        raise ValueError(f"pixels_per_unit: expected a finite number > 0, got {pixels_per_unit!r}")
    return s


def _check_radius(radius_px: int, what: str) -> None:
    if radius_px > MAX_RADIUS_PX:
        raise ValueError(
            f"{what}: the kernel would be {2 * radius_px + 1} pixels wide (radius {radius_px} px, more than "
            f"{MAX_RADIUS_PX}); lower pixels_per_unit or the scattering distance"
        )


def separable_kernel_image(kernel: SeparableKernel, pixels_per_unit) -> np.ndarray:
    """The 1-D kernel ``kernel`` at ``pixels_per_unit``: float32 (2R + 1, 3), centre at index R.

    Index R + k holds each channel's weight for the pixel k pixels along the pass (k > 0: right
    or down). Every column sums to one. A kernel whose reach is at most half a pixel gives the
    identity (1, 3) image, as ``core.techniques.ssss.technique`` leaves such pixels unchanged.
    """
    if not isinstance(kernel, SeparableKernel):
        raise ValueError(f"kernel: expected a core.optics.kernels.SeparableKernel, got {type(kernel).__name__}")
    s = _scale(pixels_per_unit)
    if len(kernel) == 1 or kernel.radius_su * s <= 0.5:
        return np.ones((1, 3), np.float32)
    pos = kernel.offsets_su * s
    radius = int(math.ceil(float(np.abs(pos).max())))
    _check_radius(radius, "separable kernel")
    out = np.zeros((2 * radius + 1, 3))
    lo = np.floor(pos)
    frac = pos - lo
    i0 = lo.astype(np.int64) + radius
    for i in range(pos.size):
        out[i0[i]] += kernel.weights[i] * (1.0 - frac[i])
        if frac[i] > 0:
            out[i0[i] + 1] += kernel.weights[i] * frac[i]
    return out.astype(np.float32)


def _centre_cell(d_px: float, cut_px: float, n_angles: int = 4096) -> float:
    """Mass of the unit-albedo profile over the centre pixel's square (|x|, |y| <= 1/2), within
    the truncation radius: (1 / 2 pi) times the integral over angles of P(min(rho, cut)), rho
    the distance to the square's edge (exact in r, the pole included; midpoint rule in angle)."""
    theta = (np.arange(n_angles) + 0.5) / n_angles * (math.pi / 4.0)  # one eighth, by symmetry
    rho = np.minimum(0.5 / np.cos(theta), cut_px)
    e3 = np.exp(-rho / (3.0 * d_px))
    cdf = 1.0 - 0.25 * e3 * e3 * e3 - 0.75 * e3
    return float(cdf.mean())  # 8 * (pi / 4) / (2 pi) = 1: the mean over the eighth is the mass


def _cells_mass(dx: np.ndarray, dy: np.ndarray, m: int, d_px: float, cut_px: float) -> np.ndarray:
    """Mass of the profile over the squares centred at (dx, dy), by an m x m midpoint rule."""
    sub = (np.arange(m) + 0.5) / m - 0.5
    x = dx[:, None, None] + sub[None, :, None]
    y = dy[:, None, None] + sub[None, None, :]
    r = np.hypot(x, y)
    e3 = np.exp(-r / (3.0 * d_px))
    f = (e3 * e3 * e3 + e3) / (8.0 * math.pi * d_px * np.maximum(r, 1e-300))
    f = np.where(r < cut_px, f, 0.0)
    return f.mean(axis=(1, 2))


def burley_kernel_image(d_su, pixels_per_unit) -> np.ndarray:
    """The Burley profile of shape ``d_su`` (R, G, B, scene units) at ``pixels_per_unit``.

    Returns float32 (2R + 1, 2R + 1, 3) with R = ceil(16 d_max pixels): each pixel holds the
    profile's mass over that pixel's square, within 16 d_max of the centre, normalized so that
    each channel sums to one. A channel whose own reach (16 d) is at most one pixel, or whose d
    is 0, is the identity (all weight on the centre), and so is the whole kernel when the widest
    channel's reach is: ``core.techniques.burley.technique`` leaves those unchanged too.

    Accuracy: the centre pixel is integrated in polar form (the 1/r pole exactly); the others by
    a midpoint rule fine enough that each pixel's relative error is about 1e-3 or less.
    """
    d = np.broadcast_to(np.asarray(d_su, dtype=np.float64), (3,))
    if np.any(~np.isfinite(d)) or np.any(d < 0):
        raise ValueError(f"d_su: expected three finite lengths >= 0 (R, G, B), got {d_su!r}")
    s = _scale(pixels_per_unit)
    d_px = d * s
    dmax = float(d_px.max())
    cut = TRUNCATION * dmax
    if cut <= 1.0:
        return np.ones((1, 1, 3), np.float32)
    radius = int(math.ceil(cut))
    _check_radius(radius, "Burley kernel")
    n = 2 * radius + 1
    ax = np.arange(n, dtype=np.float64) - radius
    grid_x, grid_y = np.meshgrid(ax, ax, indexing="xy")
    gx, gy = grid_x.ravel(), grid_y.ravel()
    dist = np.hypot(gx, gy)
    # Only the squares that reach inside the truncation circle hold any mass.
    live = dist - math.sqrt(0.5) < cut
    centre = radius * n + radius
    out = np.zeros((n * n, 3))
    for c in range(3):
        if d_px[c] <= 0 or TRUNCATION * d_px[c] <= 1.0:
            out[centre, c] = 1.0
            continue
        dc = float(d_px[c])
        # Sub-samples per side: enough that the profile's e-folding length and the 1/r falloff
        # each span several of them; beyond 24 d the exponentials are negligible and only 1/r is left.
        near = dist < 24.0 * dc
        rate = 1.0 / np.maximum(dist, 0.5) + np.where(near, 1.0 / dc, 0.0)
        m_cell = np.clip(np.ceil(10.0 * rate), 2, 64).astype(np.int64)
        m_cell[centre] = 0
        m_cell[~live] = 0
        for m in np.unique(m_cell[m_cell > 0]):
            idx = np.flatnonzero(m_cell == m)
            block = max(1, (1 << 22) // (int(m) * int(m)))
            for start in range(0, idx.size, block):
                part = idx[start : start + block]
                out[part, c] = _cells_mass(gx[part], gy[part], int(m), dc, cut)
        out[centre, c] = _centre_cell(dc, cut)
        out[:, c] /= out[:, c].sum()
    return out.reshape(n, n, 3).astype(np.float32)


def correlate_zero(image, kernel) -> np.ndarray:
    """What the Convolve node computes, in NumPy: output(p) = sum_o K[c + o] image(p + o), with
    zero outside the image; per channel for an (H, W, 3) image and a (kh, kw, 3) kernel (odd
    sizes, centre in the middle). Direct summation in float64, for tests and checks."""
    img = np.asarray(image, dtype=np.float64)
    k = np.asarray(kernel, dtype=np.float64)
    if img.ndim != 3 or k.ndim != 3 or k.shape[2] != img.shape[2]:
        raise ValueError(f"image/kernel: expected (H, W, C) and (kh, kw, C), got {img.shape} and {k.shape}")
    kh, kw = k.shape[:2]
    if kh % 2 == 0 or kw % 2 == 0:
        raise ValueError(f"kernel: expected odd sizes, got {kh} x {kw}")
    h, w = img.shape[:2]
    ry, rx = kh // 2, kw // 2
    pad = np.zeros((h + 2 * ry, w + 2 * rx, img.shape[2]))
    pad[ry : ry + h, rx : rx + w] = img
    out = np.zeros_like(img)
    for j in range(kh):
        for i in range(kw):
            weight = k[j, i]
            if np.any(weight != 0):
                out += weight * pad[j : j + h, i : i + w]
    return out


# -- the Blur-node route: the Burley profile as a sum of Gaussians --------------------------------

#: Gaussians of the Blur-node route (besides the pixel itself): six, geometrically spaced from two
#: pixels to the kernel's radius, take the route's SSS term to within about 1 % of the exact
#: profile's on the kernels of tests/core/test_kernel_images.py (the test states the bound).
BLUR_GAUSSIANS = 6

#: Smallest Blur-node size used: at size 1 the node's Gaussian is almost the pixel itself, which
#: the mixture has for free (its first weight).
MIN_BLUR_SIZE = 2


def blur_node_gaussian(size: int) -> np.ndarray:
    """The 1-D weights (2 size + 1) of the compositor Blur node's "Gaussian" filter at an integer
    Size: exp(-4.5 (i / size)^2) for |i| <= size, normalized (a Gaussian of sigma size / 3 cut at
    three sigma). Measured with bpy 5.2.3 on an impulse: equal to 2e-8 at integer sizes; fractional
    sizes differ (docs/compositor.md), so the route uses integer ones. The node is separable: its
    2-D kernel is the outer product of these weights."""
    s = int(size)
    if s < 1:
        raise ValueError(f"size: expected an integer >= 1, got {size!r}")
    i = np.arange(-s, s + 1, dtype=np.float64)
    w = np.exp(-4.5 * (i / s) ** 2)
    return w / w.sum()


def _nnls(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """min |a x - b| subject to x >= 0 (Lawson and Hanson's active-set method, docs/references.md
    §20); a has few columns here (the Gaussians), so each step is one small least-squares solve."""
    n = a.shape[1]
    passive = np.zeros(n, bool)
    x = np.zeros(n)
    scale = max(float(np.abs(a.T @ b).max()), 1e-300)
    for _ in range(3 * n + 3):
        grad = a.T @ (b - a @ x)
        if passive.all() or grad[~passive].max() <= 1e-12 * scale:
            break
        passive[int(np.argmax(np.where(passive, -np.inf, grad)))] = True
        for _ in range(3 * n + 3):
            z = np.zeros(n)
            z[passive] = np.linalg.lstsq(a[:, passive], b, rcond=None)[0]
            if np.all(z[passive] > 0):
                x = z
                break
            blocked = passive & (z <= 0)
            step = float(np.min(x[blocked] / (x[blocked] - z[blocked])))
            x = x + step * (z - x)
            passive &= x > 0
    return x


def burley_gaussian_mixture(
    d_su, pixels_per_unit, n_gaussians: int = BLUR_GAUSSIANS
) -> tuple[tuple[int, ...], np.ndarray]:
    """The Burley kernel of ``burley_kernel_image(d_su, pixels_per_unit)`` as the pixel itself plus
    Blur-node Gaussians: (sizes, weights) with ``sizes`` the Gaussians' integer Blur sizes and
    ``weights`` (1 + len(sizes), 3) float64, row 0 the pixel itself, each channel's weights >= 0
    and summing to one.

    Sizes: ``n_gaussians`` spaced geometrically from ``MIN_BLUR_SIZE`` to the kernel's radius
    (duplicates after rounding dropped). Weights: per channel, the non-negative least-squares fit
    of the mixture's 2-D kernel to the profile's, each pixel weighted by sqrt(its distance): the
    plain fit spends its freedom on the centre pixel, whose weight the pixel-itself term already
    carries, and leaves the tail (where the light of a shadow edge comes from) short.
    A kernel of one pixel gives no Gaussians and the weight (1, 1, 1) on the pixel itself.
    """
    if int(n_gaussians) != n_gaussians or n_gaussians < 1:
        raise ValueError(f"n_gaussians: expected an integer >= 1, got {n_gaussians!r}")
    target = burley_kernel_image(d_su, pixels_per_unit).astype(np.float64)
    radius = target.shape[0] // 2
    if radius < MIN_BLUR_SIZE:
        return (), np.ones((1, 3))
    sizes = tuple(int(s) for s in np.unique(np.round(np.geomspace(MIN_BLUR_SIZE, radius, int(n_gaussians)))))
    n = 2 * radius + 1
    columns = [np.zeros((n, n))]
    columns[0][radius, radius] = 1.0
    for s in sizes:
        line = np.zeros(n)
        line[radius - s : radius + s + 1] = blur_node_gaussian(s)
        columns.append(np.outer(line, line))
    basis = np.stack([c.ravel() for c in columns], axis=1)
    ax = np.arange(n) - radius
    weight = np.sqrt(np.maximum(np.hypot(*np.meshgrid(ax, ax)), 0.5)).ravel()
    out = np.zeros((basis.shape[1], 3))
    for c in range(3):
        x = _nnls(basis * weight[:, None], target[..., c].ravel() * weight)
        out[:, c] = x / x.sum() if x.sum() > 0 else np.eye(basis.shape[1])[0]
    return sizes, out


def gaussian_mixture_image(sizes, weights) -> np.ndarray:
    """The 2-D kernel (2R + 1, 2R + 1, 3) that ``sizes`` and ``weights`` of
    ``burley_gaussian_mixture`` add up to, R the largest size (1 x 1 without Gaussians)."""
    radius = max(sizes, default=0)
    n = 2 * radius + 1
    w = np.asarray(weights, dtype=np.float64)
    out = np.zeros((n, n, 3))
    out[radius, radius] += w[0]
    for k, s in enumerate(sizes, start=1):
        line = np.zeros(n)
        line[radius - s : radius + s + 1] = blur_node_gaussian(s)
        out += np.outer(line, line)[..., None] * w[k]
    return out
