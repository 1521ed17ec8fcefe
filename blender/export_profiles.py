"""Export each subsurface material's profile to where it will be used: Unity HDRP, Unreal, EEVEE.

``export_profiles(scene)`` reads every subsurface material as the passes do
(``blender.describe.sss_materials``: Burley's d from the material's inputs and mapping, the bake
distance of its objects' thickness map, the fit ``calibrate`` stored on it) and returns the
engines' values per material (``core.study.profile_export``). ``thickness_maps()`` lists the
thickness images SSS Lab baked, each converted to the bakers' convention (white = thick,
``core.scene.thickness.bakers_map``) for an engine's thickness slot. Nothing in the scene changes.
Units, formulas and sources: docs/references.md §19.
"""

from __future__ import annotations

import json
import os

import numpy as np

from ..core.base import files
from ..core.base.errors import InputError
from ..core.base.progress import printable
from ..core.pipeline.fit_params import OFF, fitted
from ..core.pipeline.mapping import burley_d, mapping_name
from ..core.scene.thickness import bakers_map
from ..core.study import png, profile_export
from .describe import sss_materials, world_corners
from .stored import META_KEY, thickness_metadata


def metres_per_unit(scene) -> float:
    """The size of one scene unit in metres: the scene's Unit Scale (Blender's ``scale_length``)."""
    return float(scene.unit_settings.scale_length)


def export_profiles(
    scene, *, technique: str = "burley", albedo_mode: str = "post", metres: float | None = None, mapping=None
) -> dict:
    """The export of every subsurface material of ``scene``: Burley's d with ``technique``'s fit
    (its ``d_scale`` and gain) when the material carries one, in each engine's fields. ``metres``:
    metres per scene unit (default: the scene's Unit Scale)."""
    m_per_unit = metres_per_unit(scene) if metres is None else float(metres)
    materials = []
    for m in sss_materials(scene):
        d = np.asarray(burley_d(m, mapping=mapping), np.float64)
        source = f"{m.method}, mapping {mapping_name(m.method, mapping)}"
        notes = list(m.notes)
        fit = fitted(m.fit, technique)
        gain: tuple[float, ...] = (1.0, 1.0, 1.0)
        if fit.get(OFF):
            notes.append(f"the fit turned {technique} off here (worse than no SSS on its frame); the unfitted profile")
        elif fit:
            if "d_scale" in fit:
                d = d * float(fit["d_scale"])
                source += f", fitted width x{float(fit['d_scale']):.3g}"
            if "gain" in fit:
                g = fit["gain"]
                gain = (float(g), float(g), float(g)) if isinstance(g, float) else tuple(float(v) for v in g)
        out = profile_export.material_export(
            m.name,
            d_su=d,
            base_color=m.base_color,
            subsurface_scale=m.subsurface_scale,
            metres_per_unit=m_per_unit,
            albedo_mode=albedo_mode,
            thickness_distance_su=m.thickness_distance,
            gain=gain,
            source=source,
        )
        if m.per_pixel:
            inputs = ", ".join(k.replace("_", " ") for k in m.per_pixel)
            notes.append(
                f"{inputs} linked to a texture or node: the exported profile uses the sockets' values (as printed"
                " above); give the engine the texture itself for what varies over the surface"
            )
        out["notes"] = notes
        materials.append(out)
    return {
        "scene": scene.name,
        "metres_per_unit": m_per_unit,
        "albedo_mode": albedo_mode,
        "technique": technique,
        "materials": materials,
    }


def thickness_maps(scene) -> list[dict]:
    """Every image SSS Lab baked a thickness map into (``blender/bake.py``), as {"image", "object",
    "distance_su", "distance_relative" (D over the object's bounding-box diagonal, the bakers'
    "relative to bounding box"), "values" (H, W) float32 in the bakers' convention, rows top to
    bottom}. Images whose pixels cannot be read are listed with "error"."""
    import bpy

    depsgraph = scene.view_layers[0].depsgraph if scene.view_layers else None
    out = []
    for image in bpy.data.images:
        meta = thickness_metadata(image) if META_KEY in image else None
        if not meta:
            continue
        item: dict = {"image": image.name, "object": meta.get("object", ""), "distance_su": meta.get("distance_su")}
        obj = bpy.data.objects.get(item["object"])
        if obj is not None and depsgraph is not None:
            corners = world_corners(obj.evaluated_get(depsgraph))
            diagonal = float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))
            if diagonal > 0 and item["distance_su"]:
                item["distance_relative"] = float(item["distance_su"]) / diagonal
        w, h = image.size
        if w < 1 or h < 1:
            item["error"] = "the image has no pixels (its file is missing?)"
            out.append(item)
            continue
        px = np.empty(w * h * image.channels, np.float32)
        image.pixels.foreach_get(px)
        values = np.clip(px.reshape(h, w, image.channels)[::-1, :, 0], 0.0, 1.0)
        item["values"] = bakers_map(values, meta.get("convention", "translucency"))
        out.append(item)
    return out


def _png_name(image_name: str, taken: set) -> str:
    import bpy

    base = bpy.path.clean_name(image_name) + "_bakers"
    name, k = base + ".png", 1
    while name in taken:
        k += 1
        name = f"{base}_{k}.png"
    taken.add(name)
    return name


def write_export(
    scene,
    folder: str,
    *,
    overwrite: bool = False,
    technique: str = "burley",
    albedo_mode: str = "post",
    metres: float | None = None,
    protect: tuple[str, ...] = (),
    log=print,
) -> tuple[dict, list[str]]:
    """Write ``folder``/profiles.json, profiles.md and each baked thickness image as
    <image>_bakers.png (16-bit, the bakers' convention); (the export, the paths written). Every file
    is checked before the first is written: none may be one of ``protect`` (the input, links
    resolved) or, without ``overwrite``, exist (InputError naming it). No material with
    subsurface scattering: nothing written, (export, [])."""
    data = export_profiles(scene, technique=technique, albedo_mode=albedo_mode, metres=metres)
    if not data["materials"]:
        return data, []
    maps, taken = [], {"profiles.json", "profiles.md"}
    for item in thickness_maps(scene):
        values = item.pop("values", None)
        if values is not None:
            item["file"] = _png_name(item["image"], taken)
        maps.append((item, values))
    data["thickness_maps"] = [item for item, _ in maps]
    writes: list[tuple[str, bytes | str]] = [
        (os.path.join(folder, item["file"]), png.encode_png16_gray(v)) for item, v in maps if v is not None
    ]
    writes += [
        (os.path.join(folder, "profiles.json"), json.dumps(data, indent=2)),
        (os.path.join(folder, "profiles.md"), profile_export.page(data)),
    ]
    protected = {os.path.realpath(p) for p in protect}
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise InputError(f"{printable(folder)!r} is a file; expected a folder for the export")
    for path, _ in writes:
        if os.path.realpath(path) in protected:
            raise InputError(f"{printable(path)!r} is an input; refusing to write over it")
        if os.path.lexists(path) and not overwrite:
            raise InputError(f"{printable(path)!r} exists; refusing to overwrite it (pass --overwrite to allow it)")
    for material in data["materials"]:
        for note in material["notes"]:  # what the reader could not read as Cycles renders it (a texture...)
            log(f"{printable(material['material'])}: {printable(note)}")
        for engine in ("hdrp", "unreal"):
            for note in material[engine]["notes"]:
                log(f"{printable(material['material'])}: {engine}: {printable(note)}")
    for item, values in maps:
        if values is None:
            log(f"thickness image {printable(item['image'])}: {printable(item['error'])}")
    os.makedirs(folder, exist_ok=True)
    written = []
    for path, content in writes:
        if isinstance(content, bytes):
            files.write_bytes(path, content)
        else:
            files.write_text(path, content)
        written.append(path)
    return data, written
