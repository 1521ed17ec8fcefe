"""A material's Burley profile in the units and fields of the engines that will render it.

SSS Lab measures and fits a Christensen–Burley profile per material: d per channel in scene units
(``core.pipeline.mapping.burley_d``, times the fit's ``d_scale``), the fit's per-channel gain on the
scattered light, the albedo mode and the thickness bake's distance D. This module writes those
numbers as Unity HDRP's diffusion profile, Unreal's Subsurface Profile and EEVEE's inputs, and reads
them back (``d_from_hdrp``, ``d_from_unreal``, ``d_from_eevee``) so that a test can hold every
conversion to its formula. Units, formulas and their sources: docs/references.md §19.

Lengths: ``metres_per_unit`` is the size of one scene unit in metres (Blender's Unit Scale); the
export assumes an asset keeps its size when it is imported, so the engines get physical lengths
(HDRP millimetres with its World Scale, Unreal centimetres with World Unit Scale 0.1). Where an
engine's range cannot hold a value, the value written is the nearest it can hold and a note says
so; nothing is clamped silently.
"""

from __future__ import annotations

import math

import numpy as np

from ..optics.profiles import albedo_scaling, burley_icdf
from .eevee_match import eevee_d, eevee_radius

#: HDRP's filter radius: the profile's 99.7 % energy radius of its widest channel (§19).
HDRP_CDF = 0.997
#: HDRP's texturing modes by SSS Lab's albedo modes (``core.base.arrays.check_albedo_mode``).
HDRP_TEXTURING = {"post": "PostScatter", "pre-post": "PreAndPostScatter"}
#: HDRP clamps World Scale (metres per unit) to at least this (DiffusionProfileSettings.Validate).
HDRP_MIN_WORLD_SCALE = 0.001
#: Unreal's d from mean free path divides by this factor times the perpendicular scaling (§19).
UNREAL_MFP_FACTOR = 0.6
#: Unreal's World Unit Scale that maps a profile millimetre to a world millimetre, its default.
UNREAL_UNIT_SCALE = 0.1
#: Ranges Unreal's Subsurface Profile clamps its fields to (SubsurfaceProfile.h, §19).
UNREAL_DISTANCE_CM = (0.1, 50.0)
UNREAL_UNIT_SCALE_RANGE = (0.1, 50.0)
UNREAL_COLOR_RANGE = (0.001, 1.0)
UNREAL_ALBEDO_RANGE = (0.01, 1.0)


def _d(d_su) -> np.ndarray:
    return _rgb(d_su, "d_su", "lengths")


def _metres(metres_per_unit) -> float:
    m = float(metres_per_unit)
    if not (math.isfinite(m) and m > 0):
        raise ValueError(f"metres_per_unit: expected a number > 0 (the scene's Unit Scale), got {metres_per_unit!r}")
    return m


def _rgb(values, what: str, kind: str = "numbers") -> np.ndarray:
    v = np.asarray(values, np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(v < 0):
        raise ValueError(f"{what}: expected three finite {kind} >= 0 (R, G, B), got {values!r}")
    return v


def _list(v) -> list[float]:
    return [float(x) for x in v]


def hdrp_profile(
    d_su,
    *,
    metres_per_unit: float,
    albedo_mode: str = "post",
    thickness_distance_su: float = 0.0,
    transmission: str = "ThinObject",
) -> dict:
    """Unity HDRP diffusion profile fields for Burley's ``d_su`` (R, G, B, scene units).

    HDRP's scattering distance is Burley's d in millimetres at World Scale 1 m per unit, shown as a
    colour (largest channel 1 here) times a multiplier; its filter radius (Max Radius, mm) is the
    99.7 % point of the widest channel. ``thickness_distance_su`` (the bake's D, 0: unknown) gives
    the thickness remap 0..D in mm for a map in the bakers' convention (``core.scene.thickness.
    bakers_map``: white = thick, the slab thickness over D). ``transmission``: "ThinObject" or
    "Regular" (HDRP's names; its inspector says Thin Object / Thick Object).
    """
    d = _d(d_su)
    m = _metres(metres_per_unit)
    if albedo_mode not in HDRP_TEXTURING:
        raise ValueError(f"albedo_mode: expected one of {', '.join(HDRP_TEXTURING)}, got {albedo_mode!r}")
    if transmission not in ("ThinObject", "Regular"):
        raise ValueError(f"transmission: expected ThinObject or Regular, got {transmission!r}")
    dist = float(thickness_distance_su)
    if not (math.isfinite(dist) and dist >= 0):
        raise ValueError(f"thickness_distance_su: expected a length >= 0 (0: unknown), got {thickness_distance_su!r}")
    d_mm = d * m * 1000.0
    notes: list[str] = []
    multiplier = float(d_mm.max())
    colour = d_mm / multiplier if multiplier > 0 else np.zeros(3)
    out = {
        "scatteringDistance": _list(colour),
        "scatteringDistanceMultiplier": multiplier,
        "scattering_distance_mm": _list(d_mm),
        "worldScale": max(m, HDRP_MIN_WORLD_SCALE),
        "texturingMode": HDRP_TEXTURING[albedo_mode],
        "transmissionMode": transmission,
        "thicknessRemap": [0.0, dist * m * 1000.0] if dist > 0 else None,
        "max_radius_mm": float(burley_icdf(HDRP_CDF, multiplier)) if multiplier > 0 else 0.0,
        "notes": notes,
    }
    if m < HDRP_MIN_WORLD_SCALE:
        notes.append(
            f"HDRP's World Scale is at least {HDRP_MIN_WORLD_SCALE} m per unit; the scene's unit is {m:g} m: "
            "scale the asset up on import and the World Scale with it"
        )
    if dist <= 0:
        notes.append("no baked thickness distance: thicknessRemap left to the artist (HDRP's default 0..5 mm)")
    return out


def d_from_hdrp(profile: dict, *, metres_per_unit: float) -> np.ndarray:
    """Burley's d (scene units) that an HDRP profile of ``hdrp_profile`` stands for."""
    colour = _rgb(profile["scatteringDistance"], "scatteringDistance")
    return colour * float(profile["scatteringDistanceMultiplier"]) / 1000.0 / _metres(metres_per_unit)


def unreal_profile(d_su, albedo, *, metres_per_unit: float) -> dict:
    """Unreal Subsurface Profile fields (Burley, mean free path) for Burley's ``d_su`` and the
    material's ``albedo`` (its Base Color; Unreal's Surface Albedo, which sets how d follows from
    the mean free path): per channel mfp = 0.6 s_perp(A) d, written as a colour (largest 1) times
    a distance in cm. Beyond Unreal's 50 cm the distance is divided and World Unit Scale
    multiplied alike (it scales the profile's lengths in the world); below 0.1 cm the value is
    the nearest Unreal holds and a note says so."""
    d = _d(d_su)
    m = _metres(metres_per_unit)
    a = np.clip(_rgb(albedo, "albedo"), *UNREAL_ALBEDO_RANGE)
    notes = []
    if not np.allclose(a, np.clip(np.asarray(albedo, np.float64), 0, None)):
        notes.append(f"Surface Albedo clamped to Unreal's {UNREAL_ALBEDO_RANGE[0]}..{UNREAL_ALBEDO_RANGE[1]}")
    mfp_cm = UNREAL_MFP_FACTOR * albedo_scaling(a, "searchlight") * d * m * 100.0
    largest = float(mfp_cm.max())
    unit_scale = UNREAL_UNIT_SCALE
    distance = largest
    lo, hi = UNREAL_DISTANCE_CM
    if largest > hi:
        k = largest / hi
        unit_scale = UNREAL_UNIT_SCALE * k
        distance = hi
        if unit_scale > UNREAL_UNIT_SCALE_RANGE[1]:
            notes.append(
                f"the mean free path {largest:.4g} cm is beyond what Unreal holds ({hi} cm at World Unit Scale "
                f"{UNREAL_UNIT_SCALE_RANGE[1]}); written at its largest"
            )
            unit_scale = UNREAL_UNIT_SCALE_RANGE[1]
    elif largest < lo:
        notes.append(
            f"the mean free path {largest:.4g} cm is below Unreal's smallest distance {lo} cm; written as {lo} cm "
            "(the profile is wider than the material's)"
        )
        distance = lo
    colour = mfp_cm / largest if largest > 0 else np.zeros(3)
    if largest > 0 and colour.min() < UNREAL_COLOR_RANGE[0]:
        notes.append(f"a mean free path colour channel below Unreal's {UNREAL_COLOR_RANGE[0]}; raised to it")
        colour = np.maximum(colour, UNREAL_COLOR_RANGE[0])
    return {
        "surface_albedo": _list(a),
        "mean_free_path_color": _list(colour),
        "mean_free_path_distance": float(distance),
        "world_unit_scale": float(unit_scale),
        "enable_burley": True,
        "enable_mean_free_path": True,
        "tint": [1.0, 1.0, 1.0],
        "transmission_tint_color": [1.0, 1.0, 1.0],
        "mean_free_path_cm": _list(mfp_cm),
        "notes": notes,
    }


def d_from_unreal(profile: dict, *, metres_per_unit: float) -> np.ndarray:
    """Burley's d (scene units) that an Unreal profile of ``unreal_profile`` stands for: d_mm =
    mfp_mm / (0.6 s_perp(A)) in profile millimetres, times World Unit Scale / 0.1 in the world."""
    a = _rgb(profile["surface_albedo"], "surface_albedo")
    mfp_cm = _rgb(profile["mean_free_path_color"], "mean_free_path_color") * float(profile["mean_free_path_distance"])
    world = float(profile["world_unit_scale"]) / UNREAL_UNIT_SCALE
    d_cm = mfp_cm / (UNREAL_MFP_FACTOR * albedo_scaling(a, "searchlight")) * world
    return d_cm / 100.0 / _metres(metres_per_unit)


def eevee_inputs(d_su, base_color, *, scale: float) -> dict:
    """EEVEE's Subsurface Radius for Burley's ``d_su`` at the material's Subsurface ``scale`` and
    ``base_color`` (EEVEE reads d = (r S / 4π) / s(A), ``core.study.eevee_match``)."""
    d = _d(d_su)
    color = _rgb(base_color, "base_color")
    return {"subsurface_radius": _list(eevee_radius(d, scale, color)), "subsurface_scale": float(scale)}


def d_from_eevee(inputs: dict, base_color) -> np.ndarray:
    """Burley's d (scene units) EEVEE gathers over with ``eevee_inputs``' values."""
    return eevee_d(inputs["subsurface_radius"], float(inputs["subsurface_scale"]), _rgb(base_color, "base_color"))


def material_export(
    name: str,
    *,
    d_su,
    base_color,
    subsurface_scale: float,
    metres_per_unit: float,
    albedo_mode: str = "post",
    thickness_distance_su: float = 0.0,
    gain=(1.0, 1.0, 1.0),
    source: str = "",
) -> dict:
    """Everything one material exports: the profile's d and the fit's gain, and the three engines'
    fields. ``gain`` (the fit's per-channel factor on the scattered light) has no profile field
    in any engine: it is given as a factor for the material's base colour (or its texture)."""
    d = _d(d_su)
    g = _rgb(gain, "gain")
    return {
        "material": name,
        "source": source,
        "d_su": _list(d),
        "d_mm": _list(d * _metres(metres_per_unit) * 1000.0),
        "base_color": _list(_rgb(base_color, "base_color")),
        "base_color_gain": _list(g),
        "thickness_distance_su": float(thickness_distance_su),
        "hdrp": hdrp_profile(
            d, metres_per_unit=metres_per_unit, albedo_mode=albedo_mode, thickness_distance_su=thickness_distance_su
        ),
        "unreal": unreal_profile(d, base_color, metres_per_unit=metres_per_unit),
        "eevee": eevee_inputs(d, base_color, scale=subsurface_scale) if subsurface_scale > 0 else None,
    }


def _f3(v) -> str:
    return ", ".join(f"{x:.4g}" for x in v)


def page(export: dict) -> str:
    """A short Markdown page of an export (``export_profiles``' JSON): per material, the values to
    type into each engine, with their units."""
    lines = [
        "# Subsurface profiles exported by SSS Lab",
        "",
        f"Scene `{export['scene']}`, one scene unit = {export['metres_per_unit']:g} m, albedo mode"
        f" {export['albedo_mode']}, profile from {export['technique']}.",
        "Lengths assume the asset keeps its size when imported. Formulas and sources: SSS Lab's"
        " docs/references.md §19.",
        "",
    ]
    for m in export["materials"]:
        h, u, e = m["hdrp"], m["unreal"], m["eevee"]
        lines += [
            f"## {m['material']}",
            "",
            f"Burley d (R, G, B): {_f3(m['d_mm'])} mm ({m['source']}); base colour gain {_f3(m['base_color_gain'])}.",
            "",
            "| engine | field | value |",
            "|---|---|---|",
            f"| Unity HDRP | Scattering Color (linear) | {_f3(h['scatteringDistance'])} |",
            f"| Unity HDRP | Multiplier | {h['scatteringDistanceMultiplier']:.4g} |",
            f"| Unity HDRP | World Scale (m per unit) | {h['worldScale']:.4g} |",
            f"| Unity HDRP | Texturing Mode | {h['texturingMode']} |",
            f"| Unity HDRP | Transmission Mode | {h['transmissionMode']} |",
            "| Unity HDRP | Thickness Remap (mm) | "
            + (f"{_f3(h['thicknessRemap'])} |" if h["thicknessRemap"] else "not baked |"),
            f"| Unity HDRP | Max Radius (mm, HDRP computes it) | {h['max_radius_mm']:.4g} |",
            f"| Unreal | Surface Albedo | {_f3(u['surface_albedo'])} |",
            f"| Unreal | Mean Free Path Color | {_f3(u['mean_free_path_color'])} |",
            f"| Unreal | Mean Free Path Distance (cm) | {u['mean_free_path_distance']:.4g} |",
            f"| Unreal | World Unit Scale | {u['world_unit_scale']:.4g} |",
            "| Unreal | Enable Burley, Enable Mean Free Path | on, on |",
        ]
        if e is not None:
            lines += [
                f"| EEVEE | Subsurface Radius | {_f3(e['subsurface_radius'])} |",
                f"| EEVEE | Subsurface Scale | {e['subsurface_scale']:.4g} |",
            ]
        notes = [f"HDRP: {n}" for n in h["notes"]] + [f"Unreal: {n}" for n in u["notes"]]
        lines += [""] + [f"- {n}" for n in notes] + ([""] if notes else [])
    return "\n".join(lines).rstrip() + "\n"
