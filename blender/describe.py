"""Read a Blender scene into SSS Lab's plain scene description (``core.scene.scene``).

Reads only; never changes the scene.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..core.scene.scene import Camera, Light, MaterialSSS, SceneDescription
from . import compat
from .stored import read_fit, thickness_metadata

_SUBSURFACE_INPUTS = {
    "subsurface_weight": "Subsurface Weight",
    "subsurface_radius": "Subsurface Radius",
    "subsurface_scale": "Subsurface Scale",
    "subsurface_ior": "Subsurface IOR",
    "subsurface_anisotropy": "Subsurface Anisotropy",
}


def _flat(matrix) -> tuple:
    return tuple(float(v) for row in matrix for v in row)


def principled_node(material):
    """The Principled BSDF that feeds the material's active output, or None."""
    if material is None or material.node_tree is None or not compat.uses_nodes(material):
        return None
    tree = material.node_tree
    output = tree.get_output_node("CYCLES") or tree.get_output_node("ALL")
    if output is not None:
        surface = output.inputs["Surface"]
        if surface.is_linked:
            node = surface.links[0].from_node
            if node.bl_idname == "ShaderNodeBsdfPrincipled":
                return node
    return next((n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"), None)


def material_sss(material, index: int) -> MaterialSSS | None:
    """The subsurface inputs of ``material``'s Principled BSDF, or None if it has none.

    Linked inputs (textures) are read at their unlinked default value.
    """
    node = principled_node(material)
    if node is None:
        return None
    values: dict[str, Any] = {}
    for key, socket_name in _SUBSURFACE_INPUTS.items():
        socket = node.inputs.get(socket_name)
        if socket is None:
            continue  # e.g. Subsurface IOR exists only for the Skin method
        value = socket.default_value
        values[key] = tuple(value)[:3] if key == "subsurface_radius" else float(value)
    base = node.inputs["Base Color"].default_value
    return MaterialSSS(
        index=index,
        name=material.name,
        method=compat.subsurface_method(node),
        base_color=tuple(min(float(c), 1.0) for c in base[:3]),
        fit=read_fit(material),
        **values,
    )


def scene_materials(scene) -> list:
    """Materials used by the visible mesh objects that the scene renders, in name order."""
    found = {}
    for obj in scene.objects:
        if obj.type != "MESH" or obj.hide_render:
            continue
        for slot in obj.material_slots:
            if slot.material is not None:
                found[slot.material.name] = slot.material
    return [found[name] for name in sorted(found)]


def bake_distance(scene, material) -> float:
    """The largest thickness-bake distance (scene units) among the scene's baked maps of
    ``material``: the metadata of its objects' meshes (attribute target) and of the images in its
    node tree (image target); 0 when none was baked by SSS Lab."""
    found = []
    for obj in scene.objects:
        if obj.type != "MESH" or obj.hide_render:
            continue
        if any(slot.material == material for slot in obj.material_slots):
            found += [meta.get("distance_su", 0.0) for meta in (thickness_metadata(obj.data) or {}).values()]
    if material.node_tree is not None:
        for node in material.node_tree.nodes:
            image = getattr(node, "image", None)
            meta = thickness_metadata(image) if image is not None else None
            if meta:
                found.append(meta.get("distance_su", 0.0))
    return max((float(d) for d in found if d > 0), default=0.0)


def sss_materials(scene, *, kept_weight=None) -> list[MaterialSSS]:
    """The scene's materials with subsurface scattering, indexed 1, 2, ... in name order, each
    with its thickness-bake distance when it has a baked map.

    ``kept_weight(material)``: for a material whose Subsurface Weight reads 0, a weight kept
    elsewhere (the compositor set-up keeps the one it saw) or None; default: none."""
    result: list[MaterialSSS] = []
    for material in scene_materials(scene):
        info = material_sss(material, len(result) + 1)
        if info is not None and not info.scatters and kept_weight is not None:
            weight = kept_weight(material)
            if weight:
                info = dataclasses.replace(info, subsurface_weight=float(weight))
        if info is not None and info.scatters:
            result.append(dataclasses.replace(info, thickness_distance=bake_distance(scene, material)))
    return result


def camera_description(scene) -> Camera:
    cam_obj = scene.camera
    if cam_obj is None:
        raise ValueError(f"scene {scene.name!r} has no active camera; set one in Scene Properties > Camera")
    cam = cam_obj.data
    render = scene.render
    scale = render.resolution_percentage / 100.0
    if cam.type not in ("PERSP", "ORTHO"):
        raise ValueError(f"camera {cam_obj.name!r}: type {cam.type!r} is not supported; expected PERSP or ORTHO")
    return Camera(
        type=cam.type,
        width_px=max(1, int(render.resolution_x * scale)),
        height_px=max(1, int(render.resolution_y * scale)),
        lens_mm=float(cam.lens),
        sensor_width_mm=float(cam.sensor_width),
        sensor_height_mm=float(cam.sensor_height),
        sensor_fit=cam.sensor_fit,
        ortho_scale=float(cam.ortho_scale),
        clip_start=float(cam.clip_start),
        clip_end=float(cam.clip_end),
        shift_x=float(cam.shift_x),
        shift_y=float(cam.shift_y),
        matrix_world=_flat(cam_obj.matrix_world),
    )


def light_descriptions(scene) -> tuple[Light, ...]:
    lights = []
    for obj in scene.objects:
        if obj.type != "LIGHT" or obj.hide_render:
            continue
        data = obj.data
        lights.append(
            Light(
                type=data.type,
                name=obj.name,
                color=tuple(data.color),
                energy=float(data.energy),
                matrix_world=_flat(obj.matrix_world),
                radius=float(getattr(data, "shadow_soft_size", 0.0)),
                size=float(getattr(data, "size", 0.0)),
                size_y=float(getattr(data, "size_y", 0.0)),
                angle=float(getattr(data, "angle", 0.0)),
                spot_size=float(getattr(data, "spot_size", 0.785398)),
                spot_blend=float(getattr(data, "spot_blend", 0.15)),
            )
        )
    return tuple(lights)


def describe_scene(scene, materials: list[MaterialSSS] | None = None, **extra) -> SceneDescription:
    import bpy

    meta = {"blender": bpy.app.version_string, "file": bpy.data.filepath, "scene": scene.name}
    meta.update(extra.pop("meta", {}))
    return SceneDescription(
        camera=camera_description(scene),
        lights=light_descriptions(scene),
        materials=tuple(materials if materials is not None else sss_materials(scene)),
        frame=scene.frame_current,
        meta=meta,
        **extra,
    )


def world_corners(obj_eval) -> np.ndarray:
    """The eight corners of the bounding box of ``obj_eval`` in world space, (8, 3) float64."""
    corners = np.array([tuple(c) for c in obj_eval.bound_box], dtype=np.float64)
    m = np.array(obj_eval.matrix_world, dtype=np.float64)
    return corners @ m[:3, :3].T + m[:3, 3]


def walk_trees(tree, seen: set):
    """``tree`` and the node groups inside it, each once."""
    if tree is None or tree.as_pointer() in seen:
        return
    seen.add(tree.as_pointer())
    yield tree
    for node in tree.nodes:
        if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None:
            yield from walk_trees(node.node_tree, seen)
