"""Plan a technique on rendered passes, without computing anything, and explain the plan.

``plan`` decides which materials of the scene description a technique computes, with which
parameters (``core.pipeline.mapping.technique_params`` and the caller's options), how wide its kernel is
in scene units and in pixels, and why every other material is left as it is;
``Plan.explain()`` says so in words. ``core.pipeline.apply.apply`` carries the plan out.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, field

import numpy as np

from ..base import arrays
from ..scene.exr import Passes
from ..scene.extent import kernel_warning, mask_extent_px
from ..scene.inputs import measured_scene
from ..scene.passes import THICKNESS
from ..scene.scene import MaterialSSS, SceneDescription
from ..techniques.registry import get_spec
from ..techniques.spec import Technique
from .call import accepted_keywords
from .zones import zones


def required_passes(technique: str | Technique, thickness_aov: str = THICKNESS) -> tuple[str, ...]:
    """The passes ``technique`` reads (its spec's ``passes``), with the thickness AOV under its
    scene name. The render enables exactly these."""
    return tuple(thickness_aov if n == THICKNESS else n for n in get_spec(technique).passes)


def _why(technique: Technique) -> str:
    return f"the {technique.label} technique"


@dataclass
class MaterialPlan:
    """What happens to one material of the scene description."""

    material: MaterialSSS
    #: Pixels whose Material Index is this material's pass index.
    pixels: int = 0
    #: (median, nearest) planar depth over those pixels (scene units; ``median_depth`` and
    #: ``nearest_depth``), None each without a Depth pass or a valid depth there.
    depths: tuple[float | None, float | None] = (None, None)
    #: Technique parameters for this material (from core.pipeline.mapping, then the caller's options).
    params: dict = field(default_factory=dict)
    #: Kernel radius in scene units per channel (R, G, B), and in pixels at the median depth.
    kernel_su: tuple[float, ...] | None = None
    kernel_px: tuple[float, ...] | None = None
    samples: int | None = None
    #: Channels (0 R, 1 G, 2 B) whose kernel is at most one pixel even at the nearest depth:
    #: composited unchanged, like a material whose every channel is that small.
    unchanged_channels: tuple[int, ...] = ()
    #: Why the material is left as it is, or None when the technique is applied to it.
    skip: str | None = None
    #: What the technique does differently on this material, and why (printed by ``explain``).
    notes: list[str] = field(default_factory=list)
    #: Said when the kernel reaches beyond the material on screen or the image (core.scene.extent).
    warning: str | None = None
    #: Where the material's d varies over its pixels (``core.pipeline.zones``): (bool (H, W) pixels,
    #: their parameters) per zone, each computed over the whole material and kept on its pixels;
    #: empty when the material is computed once with ``params``.
    zones: list = field(default_factory=list, repr=False)

    #: (Depth pass, the material's pixels) whose ``depths`` are measured when first read: a
    #: technique without a kernel needs none of them to run (only ``Plan.explain`` says them),
    #: and the median of a large material's depths took some 6 ms of STA's 1080p frame.
    depth_source: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def applied(self) -> bool:
        return self.skip is None

    @property
    def median_depth(self) -> float | None:
        """Median planar depth over the material's pixels (scene units), None without a Depth
        pass or a valid depth there."""
        return self._measured()[0]

    @property
    def nearest_depth(self) -> float | None:
        """Nearest planar depth over the material's pixels (scene units), as ``median_depth``."""
        return self._measured()[1]

    def _measured(self) -> tuple[float | None, float | None]:
        if self.depth_source is not None:
            self.depths = depth_stats(*self.depth_source)
            self.depth_source = None
        return self.depths


@dataclass
class Plan:
    """Which materials a technique computes on a set of passes, with what, and why."""

    #: The technique's name (``spec`` is its spec).
    technique: str
    shape: tuple[int, int]
    albedo_mode: str
    materials: list[MaterialPlan]
    spec: Technique
    #: Material Index values on screen that the scene description does not know (index -> pixels).
    unknown_indices: dict[int, int] = field(default_factory=dict)
    #: Pixels of applied materials with a NaN or Inf input, left as they are.
    nonfinite_pixels: int = 0
    #: Pixels whose inputs were finite but whose result was not (light near float32's limit,
    #: 3.4e38, overflowing in the technique's sums): left as they were.
    overflow_pixels: int = 0
    #: Pixels where the SSS term would have made a channel's light negative: set to 0 (passes whose
    #: diffuse light exceeds Combined).
    negative_pixels: int = 0
    #: Finite pixels of the Material Index pass that are not whole numbers, and one of their values
    #: (``fractional_indices``): said by ``index_warning``.
    fractional_index_pixels: int = 0
    fractional_index_value: float | None = None
    options: dict = field(default_factory=dict)
    #: What ``plan`` found of each scattering material's pixels (pass index -> bool (H, W)) and the
    #: Material Index pass it read them from, held weakly: ``apply`` with this plan takes them
    #: (``planned_masks``) instead of reading the pass again, if it is given the same pass.
    found: tuple = field(default=(), repr=False, compare=False)

    def planned_masks(self, passes: Passes) -> dict[int, np.ndarray]:
        """The pixels ``plan`` found per pass index if ``passes`` holds the Material Index array it
        read (the same object), else {}: a plan applied to other passes finds them again."""
        if not self.found:
            return {}
        source, masks = self.found
        return masks if source() is passes.get("Material Index") else {}

    @property
    def applied(self) -> list[MaterialPlan]:
        return [m for m in self.materials if m.applied]

    @property
    def index_warning(self) -> str | None:
        """What a Material Index pass holding values that are not whole numbers means, or None."""
        return index_warning(self.fractional_index_pixels, self.fractional_index_value)

    @property
    def scattering(self) -> list[MaterialPlan]:
        """Materials of the scene description that scatter at all (Subsurface Weight > 0 ...)."""
        return [m for m in self.materials if m.material.scatters]

    def explain(self) -> str:
        label = self.spec.label
        h, w = self.shape
        lines = [f"{label} ({self.technique}) on {w}x{h} pixels, albedo applied {self.albedo_mode}:"]
        if not self.scattering:
            lines.append("  no material in the scene description scatters light (Subsurface Weight > 0): nothing to do")
        for mp in self.materials:
            m = mp.material
            head = f"  material {m.name or '?'!r} (pass index {m.index}, {m.method})"
            if mp.skip:
                lines.append(f"{head}: left as it is: {mp.skip}")
                continue
            lines.append(f"{head}: {label}, {mp.pixels} pixels")
            if mp.median_depth is not None:
                lines.append(f"    median depth {mp.median_depth:.4g} (nearest {mp.nearest_depth:.4g}) scene units")
            if mp.kernel_su is not None:
                su = " / ".join(f"{v:.4g}" for v in mp.kernel_su)
                lines.append(f"    kernel radius R/G/B {su} scene units")
            if mp.kernel_px is not None:
                px = " / ".join(f"{v:.3g}" for v in mp.kernel_px)
                lines.append(f"    kernel radius R/G/B {px} pixels at the median depth")
            if mp.unchanged_channels:
                small = ", ".join("RGB"[c] for c in mp.unchanged_channels)
                lines.append(f"    channel {small}: kernel at most one pixel even at the nearest depth: left as it is")
            if mp.samples is not None:
                lines.append(f"    samples per pixel: {mp.samples}")
            fit = m.fit.get(self.technique)
            if fit:
                lines.append("    " + _fit_line(fit))
            lines += [f"    {note}" for note in mp.notes]
            if mp.warning:
                lines.append(f"    warning: {mp.warning}")
            shown = {k: v for k, v in mp.params.items() if _printable(v)}
            if shown:
                lines.append("    parameters: " + ", ".join(f"{k}={_fmt(v)}" for k, v in sorted(shown.items())))
        for index, count in sorted(self.unknown_indices.items()):
            lines.append(
                f"  pass index {index}: {count} pixels of a material the scene description does not list: left as is"
            )
        if self.index_warning:
            lines.append(f"  warning: {self.index_warning}")
        if self.nonfinite_pixels:
            lines.append(f"  {self.nonfinite_pixels} pixels with NaN/Inf inputs: left as they are")
        if self.overflow_pixels:
            lines.append(
                f"  {self.overflow_pixels} pixels whose result overflowed float32 (light near 3.4e38): "
                "left as they were"
            )
        if self.negative_pixels:
            lines.append(
                f"  warning: {self.negative_pixels} pixels where the passes' diffuse light (Diffuse Color x (Direct +"
                " Indirect)) exceeds Combined, so the result would be negative light: set to 0 there; the passes"
                " disagree (Combined edited or denoised apart from them, or light near float32's limit)"
            )
        applied = self.applied
        lines.append(
            f"  => {len(applied)} of {len(self.materials)} materials computed"
            + (f" ({', '.join(repr(m.material.name) for m in applied)})" if applied else "")
        )
        return "\n".join(lines)


def _fit_line(fit: dict) -> str:
    """One line on a material's fit: its values and how well it held on the held-out pixels."""
    values = ", ".join(f"{k}={_fmt(v)}" for k, v in sorted(fit.items()) if k != "info")
    info = fit.get("info") or {}
    line = f"fitted to Cycles: {values}"
    if "heldout_before" in info and "heldout_after" in info:
        line += (
            f" (Cycles random walk at {info.get('samples', '?')} samples; held-out error"
            f" {info['heldout_before']:.3g} -> {info['heldout_after']:.3g})"
        )
    return line + "; cleared by the panel's Clear Fit"


def _printable(value) -> bool:
    if isinstance(value, (bool, int, float, str)):
        return True
    if isinstance(value, (tuple, list)) and len(value) <= 4:
        return all(isinstance(v, (int, float)) for v in value)
    return False


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, (tuple, list)):
        return "(" + ", ".join(_fmt(v) for v in value) + ")"
    return repr(value) if isinstance(value, str) else str(value)


def _check_inputs(passes: Passes, scene: SceneDescription, technique: Technique, albedo_mode: str) -> None:
    arrays.check_albedo_mode(albedo_mode)
    if not isinstance(scene, SceneDescription):
        raise ValueError(f"scene: expected a SceneDescription, got {type(scene).__name__}")
    h, w = passes.shape
    cam = scene.camera
    if (cam.width_px, cam.height_px) != (w, h):
        raise ValueError(
            f"the scene description is for {cam.width_px}x{cam.height_px} pixels but the passes are {w}x{h}:"
            " they come from different renders"
        )
    for name in required_passes(technique, scene.thickness_aov):
        passes.require(name, _why(technique))


def index_map(passes: Passes) -> np.ndarray:
    """Material Index as integers; -1 where the pass is not finite (never matches a material)."""
    raw = passes["Material Index"]
    if arrays.all_finite(raw):  # the usual case: no pixel to mark
        return np.rint(raw).astype(np.int64)
    finite = np.isfinite(raw)
    out = np.full(raw.shape, -1, dtype=np.int64)
    out[finite] = np.rint(raw[finite]).astype(np.int64)
    return out


def fractional_indices(passes: Passes, rounded: np.ndarray | None = None) -> tuple[int, float | None]:
    """(finite pixels of the Material Index pass that are not whole numbers, one of their values),
    (0, None) when there are none or no such pass. Blender writes whole pass indices; a fraction
    means the pass was edited, filtered or resampled. ``rounded``: ``np.rint`` of the pass, if
    the caller has it."""
    raw = passes.get("Material Index")
    if raw is None:
        return 0, None
    off = (np.rint(raw) if rounded is None else rounded) != raw  # NaN too, told apart below
    if not off.any():
        return 0, None
    off &= np.isfinite(raw)
    count = int(np.count_nonzero(off))
    return count, (float(raw[off][0]) if count else None)


def index_warning(count: int, value: float | None) -> str | None:
    """One line on ``count`` pixels of the Material Index pass that are not whole numbers (one of
    them ``value``), or None when there are none."""
    if not count or value is None:
        return None
    nearest = int(np.rint(value))
    return (
        f"the Material Index pass has {count} pixels that are not whole numbers (such as {value:.6g}): Blender"
        " writes whole pass indices, so the pass was edited, filtered or resampled; each such pixel counts as"
        f" the nearest index ({value:.6g} as {nearest}), which may be another material's or none: render the"
        " passes again"
    )


#: Integers below this are float32 values exactly (2^24).
EXACT_FLOAT32 = 1 << 24


def _mapping():
    from . import mapping

    return mapping


def _material_params(material: MaterialSSS, technique: Technique, mapping_table, options: dict) -> dict:
    params = dict(_mapping().technique_params(material, technique, mapping=mapping_table))
    params.update(options)
    return params


def _switched_off(material: MaterialSSS, technique: Technique) -> str | None:
    """Why ``technique`` leaves ``material`` as it is when ``calibrate`` switched it off there (its
    fit's ``off``: worse than no SSS on the held-out pixels, fit and all), else None."""
    from .fit_params import OFF, fitted

    if not fitted(material.fit, technique.name).get(OFF):
        return None
    info = (material.fit.get(technique.name) or {}).get("info") or {}
    measured = ""
    if "heldout_after" in info and "heldout_none" in info:
        measured = f" (error {info['heldout_after']:.3g} against {info['heldout_none']:.3g} with no SSS)"
    return (
        f"calibrate measured {technique.label} worse than no SSS on its held-out pixels{measured}: left as it is"
        " (the panel's Clear Fit uses it again)"
    )


def _changes_level(technique: Technique, params: dict, material: MaterialSSS) -> bool:
    """True when the technique's energy model (``core/optics/energy.py``, docs/references.md §15, §17)
    gives the material Cycles' level of light, which differs from the passes' however small its
    kernel: its ``energy`` is not "lambert" and the energy tables know the material's method."""
    from ..optics.energy import CONVEX

    if "energy" not in technique.keywords:
        return False
    energy = params.get("energy", technique.defaults.get("energy", "lambert"))
    return energy != "lambert" and material.method in CONVEX


def depth_stats(depth: np.ndarray, mask: np.ndarray) -> tuple[float | None, float | None]:
    """(median, nearest) of the valid planar depths (> 0, before the background, finite) of
    ``depth`` on ``mask``; (None, None) when there is none."""
    z = depth[mask]
    valid = (z > 0) & (z < arrays.BACKGROUND_DEPTH)  # NaN and +inf fail these comparisons
    if not valid.all():
        z = z[valid]
    if not z.size:
        return None, None
    return arrays.median(z), float(z.min())  # ``z`` is a copy, without NaN


def plan(
    passes: Passes,
    scene: SceneDescription,
    technique: str | Technique,
    *,
    albedo_mode: str = "post",
    mapping=None,
    **options,
) -> Plan:
    """Decide, without computing, what ``apply`` will do.

    Raises ValueError for an unknown technique or albedo mode, a scene description that does
    not match the passes' size, or an option the technique does not take; MissingPassError
    (a KeyError) naming any missing pass and how to enable it.
    """
    p, _, masks = plan_and_masks(passes, scene, technique, albedo_mode, mapping, options)
    p.found = (weakref.ref(passes["Material Index"]), masks)
    return p


def plan_and_masks(
    passes: Passes, scene: SceneDescription, technique: str | Technique, albedo_mode: str, mapping, options: dict
) -> tuple[Plan, np.ndarray | None, dict[int, np.ndarray]]:
    """``plan``, the Material Index map (``index_map``) if it needed one (else None) and the pixels
    of each pass index of a scattering material on screen (index -> bool (H, W)), which ``apply``
    reuses."""
    technique = get_spec(technique)
    _check_inputs(passes, scene, technique, albedo_mode)
    accepted, var_kw = accepted_keywords(technique.function)
    unknown = sorted(k for k in options if k not in accepted)
    if unknown and not var_kw:
        raise ValueError(
            f"option(s) {', '.join(unknown)} not taken by {technique.name}; it takes: {', '.join(sorted(accepted))}"
        )
    raw = passes["Material Index"]
    index = None
    # The pass rounded as float32 (half the bytes of ``index_map``'s int64 map to compare): a
    # float32 holds every index below 2^24 exactly, and NaN and +-inf equal none of them, so each
    # such index has the same pixels in both. The int64 map only for the rest.
    rounded = np.rint(raw) if raw.dtype == np.float32 else None
    depth = passes.get("Depth")
    known = {m.index for m in scene.materials}
    # Each listed index's pixels from one comparison each; the map is sorted (np.unique) for the
    # unlisted indices only when some positive index on screen is not listed.
    scattering = {m.index for m in scene.materials if m.scatters}
    counts: dict[int, int] = {}
    masks: dict[int, np.ndarray] = {}
    for k in sorted(known):
        if k > 0:
            if rounded is not None and k < EXACT_FLOAT32:
                on = rounded == np.float32(k)
            else:
                index = index_map(passes) if index is None else index
                on = index == k
            counts[k] = int(np.count_nonzero(on))
            if k in scattering and counts[k]:
                masks[k] = on  # read again below and by ``apply``
    unknown_indices: dict[int, int] = {}
    listed = sum(counts.values())
    # A positive rounded value is a positive index or one the int64 map marks -1 (+inf) or cannot
    # hold: more of them than listed pixels is checked on the int64 map.
    if rounded is None or np.count_nonzero(rounded > 0) > listed:
        index = index_map(passes) if index is None else index
    if index is not None and np.count_nonzero(index > 0) > listed:
        values, numbers = np.unique(index[index > 0], return_counts=True)
        unknown_indices = {int(i): int(c) for i, c in zip(values, numbers, strict=True) if int(i) not in known}
    # Inputs the render wrote per pixel (textures, attributes...): each material's median of them.
    scene = measured_scene(passes, scene, masks)
    result = []
    for material in scene.materials:
        mp = MaterialPlan(material=material, pixels=counts.get(material.index, 0))
        result.append(mp)
        if not material.scatters:
            if material.subsurface_weight <= 0:
                mp.skip = "Subsurface Weight is 0 (a plain material)"
            elif material.subsurface_scale <= 0:
                mp.skip = "Subsurface Scale is 0 (no scattering distance)"
            else:
                mp.skip = "Subsurface Radius is 0 in every channel (no scattering distance)"
            continue
        if mp.pixels == 0:
            mp.skip = f"no pixel on screen has Material Index {material.index}"
            continue
        off = _switched_off(material, technique)
        if off:
            mp.skip = off
            continue
        mp.params = _material_params(material, technique, mapping, options)
        mp.notes += [f"note: {note}" for note in material.notes]
        if technique.prepare is not None:
            mp.notes += technique.prepare(mp.params)
        footprint = technique.footprint(mp.params)
        mp.samples = footprint.samples
        mp.kernel_su = footprint.radius_su
        mask = masks[material.index]
        found, note = zones(material, passes, mask, mapping)
        if found and note:
            mp.zones = [(z.pixels, _material_params(z.material, technique, mapping, options)) for z in found]
            mp.notes.append(note)
        if depth is not None and mp.kernel_su is None:
            mp.depth_source = (depth, mask)  # said by ``explain`` only: measured if it is read
        elif depth is not None:
            mp.depths = depth_stats(depth, mask)
            if mp.median_depth is None:
                # Scattering needs the depth of each pixel (its footprint): none has one here.
                mp.skip = (
                    "none of its pixels has a valid depth (the Depth pass is 0, negative, NaN or background "
                    "there): render the Depth pass again"
                )
                continue
        if mp.kernel_su is not None and mp.median_depth is not None:
            cam = scene.camera
            ppu_median, ppu_nearest = (
                float(v) for v in cam.pixels_per_unit(np.array([mp.median_depth, mp.nearest_depth], np.float32))
            )
            mp.kernel_px = tuple(r * ppu_median for r in mp.kernel_su)
            mp.warning = kernel_warning(max(mp.kernel_px), mask_extent_px(mask), passes.shape)
            widest_px = max(mp.kernel_su) * ppu_nearest
            # A fitted gain, the light from behind or the energy model still change a material whose
            # kernel is tiny.
            adds_light = technique.adds_light or "gain" in mp.params or _changes_level(technique, mp.params, material)
            if not adds_light:
                mp.unchanged_channels = tuple(c for c, r in enumerate(mp.kernel_su) if r * ppu_nearest <= 1.0)
            if widest_px <= 1.0 and not adds_light:
                # EEVEE Next skips a pixel whose whole footprint is at most one pixel (docs/references.md
                # §1); here even the material's nearest pixel is that small.
                mp.skip = (
                    f"its kernel is at most one pixel wide ({widest_px:.3g} px at the nearest depth"
                    f" {mp.nearest_depth:.4g}): scattering would not change it"
                )
    result_plan = Plan(
        technique=technique.name,
        spec=technique,
        shape=passes.shape,
        albedo_mode=albedo_mode,
        materials=result,
        unknown_indices=unknown_indices,
        options=dict(options),
    )
    result_plan.fractional_index_pixels, result_plan.fractional_index_value = fractional_indices(passes, rounded)
    return result_plan, index, masks
