"""How far a scattering kernel can usefully reach: the object on screen bounds it (no Blender).

Shared by the techniques that gather light from around a pixel (``core.techniques.burley.technique``,
``core.techniques.ssss.technique``), before any backend (NumPy or compiled) runs, so that every backend sees the
same bounded kernel.

Why: light only moves within an object (the techniques reject samples from other objects,
the background and the pixels the mask leaves out). A kernel much wider than the object puts
its samples or taps off the object, and the estimators then give all the weight back to the
centre pixel: a Subsurface Scale 1000 times too large (a common units slip) returned the input
unchanged, while a slightly smaller one blurred strongly. Bounding the kernel's reach by the
object's extent changes nothing the kernel could gather (there is nothing of the object beyond
it), so the result is continuous in the radius, and as the radius grows it tends to the mean
of the object's light, weighted as the profile weights distance (the Burley profile's area
density tends to 1 / r for r much smaller than d). As the radius tends to 0 the footprint
falls under one pixel and the input is kept as it is (the techniques' own rule).

``group_extents`` measures each object's extent; ``kernel_warning`` is the sentence that says
when the kernel exceeds the object or the image, for the plan and the command line.
"""

from __future__ import annotations

import math

import numpy as np

from ..base import arrays

#: ``group_extents`` finds each label's pixels with one comparison per label when the pixels
#: hold at most this many labels within a range this wide; otherwise by sorting them.
_FEW_LABELS = 8
_LABEL_RANGE = 1 << 16


def group_extents(ok: np.ndarray, scale, labels: np.ndarray | None = None) -> list[tuple[np.ndarray, float]]:
    """[(flat pixel indices, extent in scene units)] for each group of the pixels ``ok``.

    A group is the pixels sharing a ``labels`` value (object index), or all of ``ok``; groups come
    in increasing label order, each one's indices increasing. Its extent is the diagonal of its
    bounding box on screen plus one pixel, converted to scene units at its farthest pixel (the
    smallest ``scale``, pixels per scene unit): no two pixels of the group are farther apart than
    that, from any of them. ``scale``: an (H, W) array, or a function giving the scales of flat
    pixel indices (so that a caller computes them for the group's pixels only).
    """
    h, w = ok.shape
    flat = np.flatnonzero(ok)
    if flat.size == 0:
        return []
    groups: list[np.ndarray] | None = [flat]
    if labels is not None:
        lab = np.rint(np.asarray(labels).ravel()[flat].astype(np.float64)).astype(np.int64)
        groups = _few_groups(flat, lab)
        if groups is None:
            order = np.argsort(lab, kind="stable")
            cuts = np.flatnonzero(np.diff(lab[order])) + 1
            groups = [np.sort(g) for g in np.split(flat[order], cuts)]
    assert groups is not None
    scale_at = scale if callable(scale) else np.asarray(scale).ravel().__getitem__
    out = []
    for idx in groups:
        # ``idx`` increases: its first and last pixels are on its first and last rows.
        x = idx % w
        diag_px = math.hypot(float(x.max() - x.min()), float(idx[-1] // w - idx[0] // w)) + 1.0
        smallest = float(np.min(scale_at(idx)))
        extent = diag_px / smallest if smallest > 0 else math.inf
        out.append((idx, extent))
    return out


def _few_groups(flat: np.ndarray, lab: np.ndarray) -> list[np.ndarray] | None:
    """``flat`` split by ``lab`` in increasing label order (each part increasing, as ``flat``),
    with one comparison per label; None when the labels are many or spread wide (then sorting is
    cheaper)."""
    lo, hi = int(lab.min()), int(lab.max())
    if lo == hi:
        return [flat]
    if hi - lo >= _LABEL_RANGE:
        return None
    present = np.flatnonzero(np.bincount(lab - lo, minlength=hi - lo + 1))
    if present.size > _FEW_LABELS:
        return None
    return [flat[lab == lo + int(k)] for k in present]


def object_extent(ok: np.ndarray, scale: np.ndarray) -> float:
    """The extent ``group_extents`` gives the pixels ``ok`` taken as one group, without arrays of
    pixel indices (nothing the size of a frame: at 3840 x 2160 those take 66 MB each)."""
    rows = np.flatnonzero(ok.any(axis=1))
    cols = np.flatnonzero(ok.any(axis=0))
    if rows.size == 0:
        return 0.0
    diag_px = math.hypot(float(cols[-1] - cols[0]), float(rows[-1] - rows[0])) + 1.0
    smallest = float(np.min(scale, where=ok, initial=np.inf))
    return diag_px / smallest if smallest > 0 else math.inf


def mask_extent_px(mask: np.ndarray) -> float:
    """Diagonal of the bounding box of ``mask`` in pixels (plus one), 0 for an empty mask; from
    the box's rows and columns (``arrays.bounding_box``), without listing the mask's pixels."""
    box = arrays.bounding_box(mask)
    if box is None:
        return 0.0
    rows, cols = box
    return math.hypot(float(cols.stop - 1 - cols.start), float(rows.stop - 1 - rows.start)) + 1.0


def kernel_warning(kernel_px: float, object_px: float, image_shape: tuple[int, int]) -> str | None:
    """A warning when a kernel reaching ``kernel_px`` pixels exceeds the object's extent on
    screen (``object_px``, its bounding-box diagonal) or the image; None otherwise."""
    if not (kernel_px > 0) or object_px <= 0:
        return None
    h, w = image_shape
    screen = math.hypot(w, h)
    if kernel_px > screen:
        where = f"the image ({screen:.0f} px diagonal)"
    elif kernel_px > object_px:
        where = f"the material on screen ({object_px:.0f} px across)"
    else:
        return None
    return (
        f"the kernel reaches {kernel_px:.3g} px, beyond {where}: the result tends to the material's mean light "
        "(is Subsurface Scale in the scene's units?)"
    )
