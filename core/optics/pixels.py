"""The compiled start that SSSS and Burley share: one pass over the frame that finds the pixels
taking part, their light and their scale (``compiled_pixels``)."""

from __future__ import annotations

import math

import numpy as np

from ..base.arrays import float32_factor
from ..compute import backend


def _kernels():
    """This package's compiled kernels (``_kernels.py``), loaded on first use."""
    return backend.kernels(__package__)


def compiled_pixels(e, a, z, m, camera, gate: float = math.inf, threshold: float = 0.0):
    """The compiled backend's shared start of SSSS and Burley, one pass over the frame
    (``core.optics._kernels.prepare_pixels``): (albedo x diffuse, the pixels that take part, the
    camera as the kernels read it (``core.compute.jit.scale_of``), their bounding box (rows
    r0..r1 - 1, columns c0..c1 - 1) or None when there are none, ``core.scene.extent.object_extent``
    of them and their largest scale), the same values as the NumPy code's ``a * e``, ``m &
    finite_pixels(e, a, z) & (z > 0) & (z < BACKGROUND_DEPTH)`` and ``ok &= gate *
    camera.pixels_per_unit(z) > threshold`` (``gate`` +inf: ``scale > 0``). No frame of scales
    is stored: the kernels compute a pixel's from its depth."""
    f32 = np.float32
    c = np.ascontiguousarray
    h, w = m.shape
    out = np.empty((h, w, 3), f32)
    ok = np.empty((h, w), bool)
    spans = np.empty((h, 2), np.int64)
    extremes = np.empty((h, 2), f32)
    ortho = camera.type == "ORTHO"
    focal = f32(camera.ortho_px_per_unit if ortho else camera.focal_px)
    args = (c(e), c(a), c(z), c(m), ortho, focal, float32_factor(gate), f32(threshold))
    backend.run_kernel(_kernels().prepare_pixels, *args, out, ok, spans, extremes)
    cam = np.array([1.0 if ortho else 0.0, focal], f32)
    rows = np.flatnonzero(spans[:, 1] >= 0)
    if rows.size == 0:
        return out, ok, cam, None, 0.0, 0.0
    r0, r1 = int(rows[0]), int(rows[-1]) + 1
    c0, c1 = int(spans[rows, 0].min()), int(spans[rows, 1].max()) + 1
    diag_px = math.hypot(float(c1 - 1 - c0), float(r1 - 1 - r0)) + 1.0
    least = float(extremes[:, 0].min())
    extent = diag_px / least if least > 0 else math.inf
    return out, ok, cam, (r0, r1, c0, c1), extent, float(extremes[:, 1].max())
