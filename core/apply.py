"""Apply a technique to rendered passes: plan, compute, composite. No Blender needed.

The passes come from a render with the SSS materials rendered as plain diffuse (Subsurface
Weight 0, docs/references.md §7), so their diffuse light is in the Diffuse passes:
Combined = ... + Diffuse Color x (Diffuse Direct + Diffuse Indirect) + ... (the Diffuse
Direct/Indirect passes exclude the BSDF colour, docs/references.md §2). Rebuilding:

- SSSS and Burley scatter the diffuse light; on the pixels of a scattering material the image
  becomes Combined - albedo x (Direct + Indirect) + scattered, where ``scattered`` is the
  technique's albedo-applied result. Every other pixel is Combined, bit for bit.
- STA adds back-lit translucency: Combined + the STA term on the material's pixels.

Each technique gets one call per scattering material with that material's parameters
(``core.mapping.technique_params``) and a mask of the pixels whose Material Index is the
material's pass index. ``plan`` decides, without computing anything, which materials are
computed and why others are left as they are; ``Plan.explain()`` says so in words.
"""

from __future__ import annotations

import inspect
import os
import re
from dataclasses import dataclass, field

import numpy as np

from . import _arrays
from .exr import Passes
from .extent import kernel_warning, mask_extent_px
from .profiles import TRUNCATION
from .scene import MaterialSSS, SceneDescription
from .techniques import TECHNIQUES, check_technique, get_technique

#: Passes each technique reads, by their Blender 5.x names; ``THICKNESS`` stands for the scene's
#: thickness AOV (``SceneDescription.thickness_aov``, "Thickness" by default). The render
#: operator enables exactly these (see ``required_passes``). Combined is what the result is
#: composited onto; the Object Index lets Burley reject samples from other objects (EEVEE Next
#: does the same, docs/references.md §1).
THICKNESS = "Thickness"
REQUIRED_PASSES: dict[str, tuple[str, ...]] = {
    "sta": ("Combined", "Diffuse Color", "Normal", "Position", "Material Index", THICKNESS),
    "ssss": ("Combined", "Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Depth", "Material Index"),
    "burley": (
        "Combined",
        "Diffuse Direct",
        "Diffuse Indirect",
        "Diffuse Color",
        "Depth",
        "Material Index",
        "Object Index",
    ),
    "combined": (
        "Combined",
        "Diffuse Direct",
        "Diffuse Indirect",
        "Diffuse Color",
        "Depth",
        "Material Index",
        "Object Index",
        "Normal",
        "Position",
        THICKNESS,
    ),
}

ALBEDO_MODES = _arrays.ALBEDO_MODES

#: Name of the layers ``apply`` returns: ``SSSLab.<technique>.Image`` and ``.SSS``.
LAYER_PREFIX = "SSSLab"


def required_passes(technique: str, thickness_aov: str = THICKNESS) -> tuple[str, ...]:
    """The passes ``technique`` reads, with the thickness AOV under its scene name."""
    names = REQUIRED_PASSES[check_technique(technique)]
    return tuple(thickness_aov if n == THICKNESS else n for n in names)


def _why(technique: str) -> str:
    return f"the {TECHNIQUES[technique][2]} technique"


def layer_names(technique: str) -> tuple[str, str]:
    """(image layer, SSS-term layer) names for ``technique``."""
    return f"{LAYER_PREFIX}.{technique}.Image", f"{LAYER_PREFIX}.{technique}.SSS"


@dataclass
class MaterialPlan:
    """What happens to one material of the scene description."""

    material: MaterialSSS
    #: Pixels whose Material Index is this material's pass index.
    pixels: int = 0
    #: Median and nearest planar depth over those pixels (scene units), None without a Depth pass.
    median_depth: float | None = None
    nearest_depth: float | None = None
    #: Technique parameters for this material (from core.mapping, then the caller's options).
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
    #: Said when the kernel reaches beyond the material on screen or the image (core.extent).
    warning: str | None = None

    @property
    def applied(self) -> bool:
        return self.skip is None


@dataclass
class Plan:
    """Which materials a technique computes on a set of passes, with what, and why."""

    technique: str
    shape: tuple[int, int]
    albedo_mode: str
    materials: list[MaterialPlan]
    #: Material Index values on screen that the scene description does not know (index -> pixels).
    unknown_indices: dict[int, int] = field(default_factory=dict)
    #: Pixels of applied materials with a NaN or Inf input, left as they are.
    nonfinite_pixels: int = 0
    options: dict = field(default_factory=dict)

    @property
    def applied(self) -> list[MaterialPlan]:
        return [m for m in self.materials if m.applied]

    @property
    def scattering(self) -> list[MaterialPlan]:
        """Materials of the scene description that scatter at all (Subsurface Weight > 0 ...)."""
        return [m for m in self.materials if m.material.scatters]

    def explain(self) -> str:
        label = TECHNIQUES[self.technique][2]
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
        if self.nonfinite_pixels:
            lines.append(f"  {self.nonfinite_pixels} pixels with NaN/Inf inputs: left as they are")
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


def _check_inputs(passes: Passes, scene: SceneDescription, technique: str, albedo_mode: str) -> None:
    check_technique(technique)
    _arrays.check_albedo_mode(albedo_mode)
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


def _index_map(passes: Passes) -> np.ndarray:
    """Material Index as integers; -1 where the pass is not finite (never matches a material)."""
    raw = passes["Material Index"]
    finite = np.isfinite(raw)
    out = np.full(raw.shape, -1, dtype=np.int64)
    out[finite] = np.rint(raw[finite]).astype(np.int64)
    return out


def _mapping():
    from . import mapping

    return mapping


def _material_params(material: MaterialSSS, technique: str, mapping_table, options: dict) -> dict:
    params = dict(_mapping().technique_params(material, technique, mapping=mapping_table))
    params.update(options)
    return params


def _accepted(func) -> tuple[set[str], bool]:
    sig = inspect.signature(func)
    names = {p.name for p in sig.parameters.values() if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)}
    var_kw = any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values())
    return names, var_kw


def _kernel_su(technique: str, material: MaterialSSS, params: dict, mapping_table) -> tuple[float, ...] | None:
    """Kernel radius in scene units per channel: how far the technique gathers light."""
    if technique == "sta":
        return None  # local: no kernel
    d = params.get("d_su")
    if d is None and technique == "burley":
        d = _mapping().burley_d(material, mapping=mapping_table)
    if d is not None:
        # Burley and SSSS's pre-integrated kernel both reach 16 d of the profile.
        d = np.broadcast_to(np.asarray(d, dtype=np.float64), (3,))
        return tuple(float(v) * TRUNCATION for v in d)
    for key in ("radius_su", "width_su", "kernel_radius_su"):
        if key in params:
            r = np.broadcast_to(np.asarray(params[key], dtype=np.float64), (3,))
            return tuple(float(v) for v in r)
    return tuple(float(v) for v in material.radius)


def _samples(technique: str, params: dict, func) -> int | None:
    if technique == "sta":
        return None
    for key in ("n_samples", "n_taps", "taps", "samples"):
        if key in params and params[key] is not None:
            return int(params[key])
    kernel = params.get("kernel")
    if kernel is not None and hasattr(kernel, "__len__"):
        return len(kernel)
    sig = inspect.signature(func)
    for key in ("n_samples", "n_taps", "taps"):
        p = sig.parameters.get(key)
        if p is not None and p.default is not inspect.Parameter.empty and p.default is not None:
            return int(p.default)
    return None


def plan(
    passes: Passes,
    scene: SceneDescription,
    technique: str,
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
    _check_inputs(passes, scene, technique, albedo_mode)
    func = get_technique(technique)
    accepted, var_kw = _accepted(func)
    unknown = sorted(k for k in options if k not in accepted)
    if unknown and not var_kw:
        raise ValueError(
            f"option(s) {', '.join(unknown)} not taken by {technique}; it takes: {', '.join(sorted(accepted))}"
        )
    index = _index_map(passes)
    depth = passes.get("Depth")
    counts = dict(zip(*np.unique(index[index > 0], return_counts=True), strict=True))
    counts = {int(k): int(v) for k, v in counts.items()}
    known = {m.index for m in scene.materials}
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
        mp.params = _material_params(material, technique, mapping, options)
        if technique == "combined" and not mp.params.get("thickness_distance_su"):
            # The map cannot be read as a thickness without the bake's distance: diffusion only.
            mp.params["transmission_scale"] = 0.0
            mp.notes.append(
                "no light from behind: the material's thickness map has no bake distance (bake it with"
                " SSS Lab's Bake Thickness); diffusion only"
            )
        mp.samples = _samples(technique, mp.params, func)
        mp.kernel_su = _kernel_su(technique, material, mp.params, mapping)
        if depth is not None:
            z = depth[index == material.index]
            z = z[np.isfinite(z) & (z > 0) & (z < _arrays.BACKGROUND_DEPTH)]
            if z.size:
                mp.median_depth = float(np.median(z))
                mp.nearest_depth = float(z.min())
        if mp.kernel_su is not None and mp.median_depth is not None:
            cam = scene.camera
            ppu_median, ppu_nearest = (
                float(v) for v in cam.pixels_per_unit(np.array([mp.median_depth, mp.nearest_depth], np.float32))
            )
            mp.kernel_px = tuple(r * ppu_median for r in mp.kernel_su)
            mp.warning = kernel_warning(max(mp.kernel_px), mask_extent_px(index == material.index), passes.shape)
            widest_px = max(mp.kernel_su) * ppu_nearest
            # A fitted gain or the light from behind still change a material whose kernel is tiny.
            adds_light = technique == "combined" or "gain" in mp.params
            if not adds_light:
                mp.unchanged_channels = tuple(c for c, r in enumerate(mp.kernel_su) if r * ppu_nearest <= 1.0)
            if widest_px <= 1.0 and not adds_light:
                # EEVEE Next skips a pixel whose whole footprint is at most one pixel (docs/references.md
                # §1); here even the material's nearest pixel is that small.
                mp.skip = (
                    f"its kernel is at most one pixel wide ({widest_px:.3g} px at the nearest depth"
                    f" {mp.nearest_depth:.4g}): scattering would not change it"
                )
    unknown_indices = {i: c for i, c in counts.items() if i not in known}
    return Plan(
        technique=technique,
        shape=passes.shape,
        albedo_mode=albedo_mode,
        materials=result,
        unknown_indices=unknown_indices,
        options=dict(options),
    )


def _finite(a: np.ndarray) -> np.ndarray:
    """Per-pixel finiteness of an (H, W) or (H, W, C) array."""
    ok = np.isfinite(a)
    return ok.all(axis=-1) if a.ndim == 3 else ok


def _clean(a: np.ndarray) -> np.ndarray:
    """A float32 copy with NaN and +-Inf replaced by 0 (no other value changes; nothing clamped)."""
    out = np.array(a, dtype=np.float32)
    out[~np.isfinite(out)] = 0.0
    return out


def _call(func, kwargs: dict):
    accepted, var_kw = _accepted(func)
    if not var_kw:
        kwargs = {k: v for k, v in kwargs.items() if k in accepted}
    return func(**kwargs)


def apply(
    passes: Passes,
    scene: SceneDescription,
    technique: str,
    *,
    albedo_mode: str = "post",
    mapping=None,
    prepared: Plan | None = None,
    **options,
) -> dict[str, np.ndarray]:
    """Run ``technique`` on every scattering material and composite the result.

    Returns the new layers, float32, rows top to bottom:
    ``SSSLab.<technique>.Image`` (H, W, C) with C and the alpha of Combined, and
    ``SSSLab.<technique>.SSS`` (H, W, 3), the SSS term alone (scattered minus the original
    diffuse for SSSS and Burley, the added light for STA). Pixels of materials that do not
    scatter, are skipped by the plan, or have a NaN/Inf input keep Combined exactly (SSS 0).
    When no material scatters, returns {} (nothing to write).

    ``albedo_mode``: "post" applies the albedo after scattering (out = A * scatter(E));
    "pre-post" splits it, out = sqrt(A) * scatter(sqrt(A) * E), keeping half of the texture
    detail under the blur (Jimenez et al. 2015, the separable SSS demo's pre/post scatter
    option). STA does not scatter and ignores it. ``prepared`` is the result of ``plan`` for
    the same arguments, to avoid planning twice.
    """
    p = prepared or plan(passes, scene, technique, albedo_mode=albedo_mode, mapping=mapping, **options)
    if not p.scattering:
        return {}
    func = get_technique(technique)
    combined = passes["Combined"]
    rgb = combined[..., :3]
    image = np.array(combined, dtype=np.float32)
    sss = np.zeros(rgb.shape, dtype=np.float32)
    index = _index_map(passes)
    albedo_raw = passes["Diffuse Color"]
    albedo = _clean(albedo_raw)
    ok = _finite(rgb) & _finite(albedo_raw)
    inputs = {}
    if technique in ("sta", "combined"):
        thickness_raw = passes[scene.thickness_aov]
        normal_raw, position_raw = passes["Normal"], passes["Position"]
        ok &= _finite(thickness_raw) & _finite(normal_raw) & _finite(position_raw)
        inputs = {
            "albedo": albedo,
            "normal": _clean(normal_raw),
            "position": _clean(position_raw),
            "thickness": _clean(thickness_raw if thickness_raw.ndim == 2 else thickness_raw[..., 0]),
            "camera": scene.camera,
            "lights": scene.lights,
            "thickness_convention": scene.thickness_convention,
        }
    if technique != "sta":
        direct, indirect = passes["Diffuse Direct"], passes["Diffuse Indirect"]
        depth_raw = passes["Depth"]
        ok &= _finite(direct) & _finite(indirect) & _finite(depth_raw)
        diffuse = _clean(direct) + _clean(indirect)
        original = albedo * diffuse  # the diffuse light Combined holds on these pixels
        pre, tech_albedo = _arrays.split_albedo(albedo, albedo_mode)
        tech_diffuse = diffuse if pre is None else pre * diffuse
        inputs |= {
            "diffuse": tech_diffuse,
            "albedo": tech_albedo,
            # Invalid depth becomes background (1e10), which gives and receives no light.
            "depth": np.where(np.isfinite(depth_raw), depth_raw, np.float32(1e10)).astype(np.float32),
            "camera": scene.camera,
        }
        if technique in ("burley", "combined"):
            inputs["object_id"] = _clean(passes["Object Index"])
    nonfinite = 0
    for mp in p.applied:
        mask = index == mp.material.index
        nonfinite += int((mask & ~ok).sum())
        mask &= ok
        if not mask.any():
            continue
        kwargs = dict(inputs)
        kwargs.update(mp.params)
        # A technique that takes the fitted gain applies it itself (the combined technique, to its
        # diffusion only); for the others it scales their result below.
        gain = None if "gain" in _accepted(func)[0] else kwargs.pop("gain", None)
        kwargs["mask"] = mask
        out = np.asarray(_call(func, kwargs), dtype=np.float32)
        if out.shape != rgb.shape:
            raise ValueError(f"{technique} returned shape {out.shape}; expected {rgb.shape}")
        if gain is not None:
            # The fitted per-channel energy (core/fit_params.py): on the material's light after the
            # technique (for STA, on the light it adds).
            out = out * np.asarray(gain, np.float32)
        good = mask & _finite(out)
        nonfinite += int((mask & ~good).sum())
        if technique == "sta":
            term = out
        else:
            term = out - original
            if mp.unchanged_channels:
                term = term.copy()
                term[..., list(mp.unchanged_channels)] = 0.0
        image[..., :3][good] = rgb[good] + term[good]
        sss[good] = term[good]
    p.nonfinite_pixels = nonfinite
    name_image, name_sss = layer_names(technique)
    return {name_image: image, name_sss: sss}


# --- Files and frame sequences (what ``python -m sss_lab apply`` does, without the printing) ---

#: Exit status of the command line when no material of the scene scatters (nothing written).
EXIT_NOTHING_TO_DO = 3

_HASHES = re.compile(r"#+")


def parse_methods(text: str) -> list[str]:
    """``"burley"``, ``"sta,ssss"`` or ``"all"`` -> technique names; ValueError lists the known ones."""
    names = [t.strip() for t in str(text).split(",") if t.strip()]
    if not names:
        raise ValueError(f"method: expected one of {', '.join(TECHNIQUES)} or all, got {text!r}")
    if names == ["all"]:
        return list(TECHNIQUES)
    out = []
    for name in names:
        try:
            check_technique(name)
        except ValueError:
            raise ValueError(f"unknown method {name!r}; expected one of: {', '.join(TECHNIQUES)}, all") from None
        if name not in out:
            out.append(name)
    return out


#: The most frames one run takes: a range beyond it is a typing slip (1-100000000), not a job.
MAX_FRAMES = 100_000


def parse_frames(text: str) -> list[int]:
    """``"1-5"``, ``"7"``, ``"1-3,8"`` -> sorted frame numbers (inclusive ranges), at most
    ``MAX_FRAMES`` of them (checked before any list is built)."""
    frames: set[int] = set()
    total = 0
    for chunk in str(text).split(","):
        chunk = chunk.strip()
        m = re.fullmatch(r"(-?\d+)(?:\s*(?:-|\.\.)\s*(-?\d+))?", chunk)
        if not m:
            raise ValueError(f"frames: {chunk!r} is not a frame or a range like 1-10")
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
        if b < a:
            raise ValueError(f"frames: range {chunk!r} ends before it starts")
        total += b - a + 1
        if total > MAX_FRAMES:
            raise ValueError(
                f"frames: {text!r} holds more than {MAX_FRAMES} frames, the most one run takes; split the range, "
                "or leave --frames out to take every existing file"
            )
        frames.update(range(a, b + 1))
    return sorted(frames)


def is_sequence(path: str) -> bool:
    """True when ``path`` holds a ``#`` frame pattern (``passes_####.exr``)."""
    return "#" in os.path.basename(os.fspath(path))


def frame_path(pattern: str, frame: int) -> str:
    """Replace the last run of ``#`` in the file name by ``frame``, zero-padded to its length
    (as Blender names rendered frames; more digits when the frame needs them)."""
    folder, name = os.path.split(os.fspath(pattern))
    runs = list(_HASHES.finditer(name))
    if not runs:
        return os.fspath(pattern)
    run = runs[-1]
    number = f"-{abs(frame):0{run.end() - run.start()}d}" if frame < 0 else f"{frame:0{run.end() - run.start()}d}"
    return os.path.join(folder, name[: run.start()] + number + name[run.end() :])


def sequence_frames(pattern: str, frames: list[int] | None = None) -> list[tuple[int | None, str]]:
    """The (frame, path) pairs of ``pattern``: the given frames, or every existing file that
    matches the pattern, in frame order. A path without ``#`` is one file with frame None."""
    pattern = os.fspath(pattern)
    if not is_sequence(pattern):
        if frames:
            raise ValueError(f"--frames needs a frame pattern with # in the file name, got {pattern!r}")
        return [(None, pattern)]
    if frames:
        return [(f, frame_path(pattern, f)) for f in frames]
    folder, name = os.path.split(pattern)
    run = list(_HASHES.finditer(name))[-1]
    regex = re.compile(
        re.escape(name[: run.start()]) + rf"(-?\d{{{run.end() - run.start()},}})" + re.escape(name[run.end() :]) + r"\Z"
    )
    found = []
    for entry in os.listdir(folder or "."):
        m = regex.match(entry)
        if m:
            found.append((int(m.group(1)), os.path.join(folder, entry)))
    if not found:
        raise FileNotFoundError(f"no file matches the frame pattern {pattern!r}")
    return sorted(found)


def default_output(path: str) -> str:
    """``passes.exr`` -> ``passes.sss.exr`` (beside the input)."""
    stem, _ = os.path.splitext(os.fspath(path))
    return stem + ".sss.exr"


def sidecar_path(path: str) -> str:
    """The scene description written beside a passes file: same stem, ``.json``."""
    stem, _ = os.path.splitext(os.fspath(path))
    return stem + ".json"


def load_scene(exr_path: str, scene_path: str | None = None) -> SceneDescription:
    """The scene description for ``exr_path``: ``scene_path`` if given, else the sidecar JSON."""
    path = scene_path or sidecar_path(exr_path)
    if not os.path.isfile(path):
        hint = "" if scene_path else " (the render writes it beside the EXR; or pass --scene PATH)"
        raise FileNotFoundError(f"{path}: no scene description{hint}")
    return read_scene_file(path)


def read_scene_file(path: str) -> SceneDescription:
    """A scene description JSON file, checked (``SceneDescription.from_dict``); InputError names
    the file and what is wrong, also for a file that is not JSON text at all (an EXR, say)."""
    from .errors import InputError
    from .exr import EXR_MAGIC

    with open(path, "rb") as fh:
        raw = fh.read()
    if raw.startswith(EXR_MAGIC):
        raise InputError(f"{path}: is an OpenEXR file, not a scene description; pass the .json written beside the EXR")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(
            f"{path}: not a scene description (not UTF-8 text: byte {exc.start}); pass the .json written beside the EXR"
        ) from None
    try:
        return SceneDescription.from_json(text)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None


@dataclass
class FileResult:
    """What ``apply_file`` did with one passes file."""

    path: str
    out_path: str
    scene: SceneDescription | None = None
    plans: dict = field(default_factory=dict)
    #: Techniques not run, with the reason (a missing pass when all techniques were asked for).
    skipped: dict = field(default_factory=dict)
    #: True when no material of the scene scatters: nothing is written.
    nothing_to_do: bool = False
    written: bool = False


def apply_file(
    path: str,
    techniques: list[str],
    *,
    out_path: str | None = None,
    scene: SceneDescription | None = None,
    scene_path: str | None = None,
    albedo_mode: str = "post",
    explain: bool = False,
    overwrite: bool = False,
    skip_missing: bool = False,
    view_layer: str | None = None,
    mapping=None,
    **options,
) -> FileResult:
    """Apply ``techniques`` to one passes file and write ``out_path`` (default ``<stem>.sss.exr``).

    The output holds every layer of the input (float32) plus, per technique,
    ``SSSLab.<technique>.Image`` and ``SSSLab.<technique>.SSS``; its header keeps the input's
    metadata and adds the scene description (``sss_lab.scene``, JSON). With ``explain`` it only
    plans. When no material scatters, nothing is written (``nothing_to_do``). With
    ``skip_missing`` a technique whose passes are missing is skipped (reason in ``skipped``)
    instead of raising, unless every technique is.
    """
    from .exr import MissingPassError, passes_from_contents, read_layers, write_layers

    path = os.fspath(path)
    out_path = os.fspath(out_path) if out_path else default_output(path)
    if os.path.abspath(out_path) == os.path.abspath(path):
        raise FileExistsError(f"{out_path} is the input file; refusing to overwrite it")
    # The scene description is an input too (sidecar or --scene): never written over, however spelled.
    inputs = [path, scene_path or sidecar_path(path)]
    for source in inputs:
        if os.path.exists(out_path) and os.path.exists(source) and os.path.samefile(out_path, source):
            raise FileExistsError(f"{out_path} is an input of this computation ({source}); refusing to overwrite it")
    if not out_path.lower().endswith(".exr"):
        raise ValueError(f"--out {out_path!r}: the output is a multilayer OpenEXR file; give it the .exr suffix")
    result = FileResult(path=path, out_path=out_path)
    contents = read_layers(path)
    passes = passes_from_contents(contents, view_layer)
    result.scene = scene = scene if scene is not None else load_scene(path, scene_path)
    for technique in techniques:
        try:
            result.plans[technique] = plan(
                passes, scene, technique, albedo_mode=albedo_mode, mapping=mapping, **options
            )
        except MissingPassError as exc:
            if not skip_missing:
                raise
            result.skipped[technique] = str(exc)
    if not result.plans:
        raise MissingPassError("none of the techniques can run on these passes:\n" + "\n".join(result.skipped.values()))
    if not any(p.scattering for p in result.plans.values()):
        result.nothing_to_do = True
        return result
    if explain:
        return result
    if os.path.isdir(out_path):
        raise FileExistsError(f"{out_path} is a folder; give the output a file name (--out FOLDER/NAME.exr)")
    if os.path.exists(out_path) and not overwrite:
        raise FileExistsError(f"{out_path} already exists; refusing to overwrite it (use --overwrite or --out)")
    layers = dict(contents.layers)
    channels = dict(contents.channels)
    for technique, p in result.plans.items():
        new = apply(passes, scene, technique, albedo_mode=albedo_mode, mapping=mapping, prepared=p, **options)
        for name in new:
            channels.pop(name, None)
        layers.update(new)
    header = dict(contents.header)
    header["sss_lab.scene"] = scene.to_json()
    header["sss_lab.methods"] = ",".join(result.plans)
    header["sss_lab.albedo_mode"] = albedo_mode
    write_layers(
        out_path, layers, header, channels=channels, overwrite=overwrite, inputs=inputs, windows=contents.windows
    )
    result.written = True
    return result
