"""Subsurface inputs that vary over a material, read from the render that made the passes.

A material whose Base Color, Subsurface Radius, Scale or Weight is linked to a texture, an
attribute or a node the scene reader cannot read as a constant carries those inputs' names in
``MaterialSSS.per_pixel``; the passes render writes each such input into a shader AOV
(``core.scene.passes.INPUT_AOVS``) fed by the same link, so Cycles evaluates it exactly, node
groups, drivers and all. This module reads them back:

- ``measured_scene`` gives each such material the median of its pixels per input (per channel
  for a colour) in place of the socket's value, with a note saying what was read and over how
  many pixels; the plan, the mapping, the energy stage, the fit and ``auto`` work from it.
- ``weight_map`` is the per-pixel Subsurface Weight ``apply`` blends with.

The median is taken over the material's interior pixels (its mask shrunk by one pixel when that
leaves enough): an AOV is filtered like the image, so a pixel on the silhouette holds the value
times the pixel's coverage, not the value (a probe render gave 0.28 for 0.37 on an edge). A
negative value is read as 0 and a colour above 1 as 1 where Cycles clamps them (Radius x Scale
and Subsurface Weight at 0, Base Color to 0..1; docs/references.md §2), and counted in the note;
a value that is not finite is left out and counted. When no pixel holds a finite value the
socket's value stays, and the note says so; an AOV missing from the passes (a file rendered
without it) is said the same way.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..base import arrays
from .exr import Passes
from .passes import INPUT_AOVS
from .scene import MaterialSSS, SceneDescription

#: Interior pixels needed before the shrunk mask is used instead of the whole one.
MIN_INTERIOR = 16

_LABELS = {
    "base_color": "Base Color",
    "subsurface_radius": "Subsurface Radius",
    "subsurface_scale": "Subsurface Scale",
    "subsurface_weight": "Subsurface Weight",
}


def interior(mask: np.ndarray) -> np.ndarray:
    """``mask`` without its pixels that touch a pixel outside it (4-neighbours; the image's
    border counts as outside), or ``mask`` itself when fewer than ``MIN_INTERIOR`` would stay."""
    inner = mask.copy()
    inner[1:, :] &= mask[:-1, :]
    inner[:-1, :] &= mask[1:, :]
    inner[:, 1:] &= mask[:, :-1]
    inner[:, :-1] &= mask[:, 1:]
    inner[0, :] = inner[-1, :] = False
    inner[:, 0] = inner[:, -1] = False
    return inner if np.count_nonzero(inner) >= MIN_INTERIOR else mask


def _channels(raw: np.ndarray, kind: str) -> np.ndarray:
    """The AOV's channels that carry the input: RGB of a colour AOV, the first of a value AOV."""
    if raw.ndim == 2:
        return raw[..., None] if kind == "VALUE" else np.repeat(raw[..., None], 3, axis=2)
    return raw[..., :1] if kind == "VALUE" else raw[..., :3]


def _as_cycles(values: np.ndarray, key: str) -> np.ndarray:
    """``values`` of input ``key`` clamped in place as Cycles' closure clamps them: no negative
    radius, scale or weight; Base Color and Weight at most 1. Returns ``values``."""
    np.maximum(values, 0.0, out=values)
    if key in ("base_color", "subsurface_weight"):
        np.minimum(values, 1.0, out=values)
    return values


def measure(material: MaterialSSS, passes: Passes, mask: np.ndarray) -> MaterialSSS:
    """``material`` with each of its ``per_pixel`` inputs replaced by the median of its AOV over
    the material's pixels ``mask`` (bool (H, W)); a note per input says what was read, or why the
    socket's value stays."""
    if not material.per_pixel:
        return material
    changes: dict = {}
    notes = list(material.notes)
    where = interior(mask)
    for key in material.per_pixel:
        aov = INPUT_AOVS[key]
        label = _LABELS[key]
        current = getattr(material, key)
        if aov.name not in passes.names:
            notes.append(
                f"{label}: the passes have no {aov.name!r} AOV (rendered without it): its socket's value "
                f"{_fmt(current)} is used; render the passes again to read it per pixel"
            )
            continue
        values = _channels(passes[aov.name], aov.kind)[where]  # (n, channels), a copy
        usable = np.isfinite(values).all(axis=1)
        left_out = int(values.shape[0] - np.count_nonzero(usable))
        if not usable.any():
            notes.append(
                f"{label}: the {aov.name!r} AOV holds no finite value on the material's {values.shape[0]} pixels "
                f"(NaN or infinite): its socket's value {_fmt(current)} is used instead"
            )
            continue
        values = values[usable]
        negative = int(np.count_nonzero((values < 0).any(axis=1)))
        _as_cycles(values, key)
        med = tuple(arrays.median(np.array(values[:, c])) for c in range(values.shape[1]))
        value = med if aov.kind == "COLOR" else med[0]
        lo, hi = np.percentile(values.max(axis=1), (5, 95))
        line = (
            f"{label}: read from the render ({aov.name!r} AOV): median {_fmt(value)} over {values.shape[0]} pixels"
            f" (5th-95th percentile {lo:.3g}-{hi:.3g})"
        )
        if left_out:
            line += f"; {left_out} pixels NaN or infinite left out"
        if negative:
            line += f"; {negative} pixels negative, read as 0 as Cycles does"
        notes.append(line)
        changes[key] = value
    return dataclasses.replace(material, notes=tuple(notes), per_pixel=material.per_pixel, measured=True, **changes)


def usable_map(material: MaterialSSS, passes: Passes, key: str, where: np.ndarray) -> np.ndarray | None:
    """Input ``key``'s AOV on the pixels ``where`` (float64 (n, channels)), as Cycles uses it:
    negatives 0, Base Color at most 1; the material's own value where the AOV is not finite.
    None when the passes have no such AOV."""
    aov = INPUT_AOVS[key]
    if aov.name not in passes.names:
        return None
    values = np.array(_channels(passes[aov.name], aov.kind)[where], dtype=np.float64)
    bad = ~np.isfinite(values)
    if bad.any():
        own = np.broadcast_to(np.asarray(getattr(material, key), np.float64).reshape(-1), values.shape[1:])
        values = np.where(bad, own, values)
    return _as_cycles(values, key)


def measured_scene(passes: Passes, scene: SceneDescription, masks: dict[int, np.ndarray]) -> SceneDescription:
    """``scene`` with ``measure`` applied to each material that has per-pixel inputs and pixels
    in ``masks`` (pass index -> bool (H, W)); ``scene`` itself when there is none (the usual
    case, free). A material measured already (``MaterialSSS.measured``) is kept as it is."""
    todo = [m for m in scene.materials if m.per_pixel and not m.measured and m.index in masks]
    if not todo:
        return scene
    done = {m.index: measure(m, passes, masks[m.index]) for m in todo}
    return dataclasses.replace(scene, materials=tuple(done.get(m.index, m) for m in scene.materials))


def read_scene(passes: Passes, scene: SceneDescription) -> SceneDescription:
    """``measured_scene`` with each material's pixels found from the Material Index pass (for a
    caller without the plan's masks: the fit, ``auto``, the comparison's report); ``scene`` itself,
    without reading the pass, when no material reads an input per pixel."""
    todo = [m for m in scene.materials if m.per_pixel and not m.measured]
    if not todo or "Material Index" not in passes.names:
        return scene
    index = np.rint(passes["Material Index"])
    masks = {m.index: index == m.index for m in todo}
    return measured_scene(passes, scene, {k: on for k, on in masks.items() if on.any()})


def weight_map(material: MaterialSSS, passes: Passes, mask: np.ndarray) -> np.ndarray | None:
    """The material's Subsurface Weight per pixel over ``mask`` (float32 (H, W), clipped to 0..1),
    or None when its weight is one number. Where the AOV is not finite, and on the mask's edge
    (whose AOV holds the weight times the pixel's coverage), the material's own weight (its
    median once measured) stands in."""
    aov = INPUT_AOVS["subsurface_weight"]
    if "subsurface_weight" not in material.per_pixel or aov.name not in passes.names:
        return None
    raw = np.array(_channels(passes[aov.name], aov.kind)[..., 0], dtype=np.float32)
    stand_in = ~np.isfinite(raw) | (mask & ~interior(mask))
    if stand_in.any():
        raw[stand_in] = material.subsurface_weight
    return _as_cycles(raw, "subsurface_weight")


def _fmt(value) -> str:
    if isinstance(value, (tuple, list)):
        return "(" + ", ".join(f"{float(v):.4g}" for v in value) + ")"
    return f"{float(value):.4g}"
