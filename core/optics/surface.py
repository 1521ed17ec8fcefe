"""The surface a pixel covers, over that of a pixel facing the camera: what Burley's samples and
SSSS's taps are weighted by (docs/references.md §17)."""

from __future__ import annotations

import numpy as np

from ..base import arrays
from ..scene.scene import Camera
from .energy import view_cosine

#: ``surface_area`` is at most 1 / MIN_VIEW_COSINE: a pixel covers at most 5 times the surface of
#: one facing the camera (a silhouette's pixel would otherwise weigh without bound).
MIN_VIEW_COSINE = 0.2


def surface_area(depth, ok, camera: Camera) -> np.ndarray:
    """The surface each pixel of ``ok`` covers over that of a pixel at its place in the image on a
    plane at its depth facing the camera's axis: cos a / cos, with cos the view cosine from the
    Depth pass (``core.optics.energy.view_cosine``, on the pixels' bounding box) and a the angle of the
    pixel's ray to the axis (0 for an orthographic camera), at most 1 / ``MIN_VIEW_COSINE``;
    float32 (H, W), C-contiguous; 1 elsewhere and where the view cosine is unknown (no neighbour
    on ``ok``: view_cosine's 1). A spiral sample stands for the screen area around it, which the
    pixels' scale already turns into the surface of a plane facing the axis at that depth; a
    surface turned away from it is cos a / cos times as large: at a silhouette, where the cosine
    falls to 0, the samples on the rim are the larger part of the surface the kernel covers, not
    the lit interior's (docs/references.md §17). A plane facing the axis reads 1 everywhere."""
    ok = np.asarray(ok, dtype=bool)
    out = np.ones(ok.shape, np.float32)
    if not ok.any():
        return out
    rows, cols = np.flatnonzero(ok.any(axis=1)), np.flatnonzero(ok.any(axis=0))
    box = (slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1))
    cos = view_cosine(np.asarray(depth)[box], ok[box], camera, origin=(box[0].start, box[1].start), frame=ok.shape)
    axis = np.ones(cos.shape, np.float64)
    if camera.type != "ORTHO":
        h, w = ok.shape
        f = camera.focal_px
        cx, cy = camera.principal_point(w, h)
        ys, xs = np.mgrid[box[0], box[1]].astype(np.float64)
        axis = 1.0 / np.sqrt(1.0 + ((xs + 0.5 - cx) / f) ** 2 + ((cy - ys - 0.5) / f) ** 2)
    ratio = np.minimum(axis / np.maximum(cos.astype(np.float64), 1e-30), 1.0 / MIN_VIEW_COSINE)
    out[box] = np.where(ok[box] & (cos < 1.0), ratio, 1.0).astype(np.float32)
    return out


def surface_area_args(camera: Camera, shape, min_cos: float) -> tuple:
    """The compiled kernels' parameters of ``surface_area`` after the depth and ``ok``
    (``core.optics._kernels.area_at``): the background depth, whether the camera is orthographic, its
    pixels per unit (orthographic) or focal length in pixels, its principal point, as
    ``surface_area`` unprojects pixels, and the smallest view cosine ``min_cos``."""
    h, w = shape
    ortho = camera.type == "ORTHO"
    f = float(camera.ortho_px_per_unit if ortho else camera.focal_px)
    cx, cy = camera.principal_point(w, h)
    return np.float32(arrays.BACKGROUND_DEPTH), ortho, f, cx, cy, min_cos
