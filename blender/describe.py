"""Read a Blender scene into SSS Lab's plain scene description (``core.scene.scene``).

Reads only; never changes the scene.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..core.scene.passes import INPUT_AOVS
from ..core.scene.scene import Camera, Light, MaterialSSS, SceneDescription
from . import compat
from .shader_graph import PRINCIPLED, SUBSURFACE, input_value, principled_sources, renders_an_output
from .stored import read_fit, thickness_metadata

#: The Subsurface Scattering node's inputs by the same keys (its Weight is the node itself: 1).
_NODE_INPUTS = {
    "subsurface_radius": "Radius",
    "subsurface_scale": "Scale",
    "subsurface_ior": "IOR",
    "subsurface_anisotropy": "Anisotropy",
    "base_color": "Color",
}
_SUBSURFACE_INPUTS = {
    "subsurface_weight": "Subsurface Weight",
    "subsurface_radius": "Subsurface Radius",
    "subsurface_scale": "Subsurface Scale",
    "subsurface_ior": "Subsurface IOR",
    "subsurface_anisotropy": "Subsurface Anisotropy",
}


def _input_names(node) -> dict[str, str]:
    """``MaterialSSS`` field -> the input socket of ``node`` (a Principled BSDF or a Subsurface
    Scattering node) that holds it."""
    return _NODE_INPUTS if node.bl_idname == SUBSURFACE else {**_SUBSURFACE_INPUTS, "base_color": "Base Color"}


def _flat(matrix) -> tuple:
    return tuple(float(v) for row in matrix for v in row)


def principled_node(material):
    """The Principled BSDF whose closure reaches the material's active output (through Mix and
    Add Shaders, reroutes and node groups: ``shader_graph.principled_sources``; the one that
    scatters most when several do), else the first Principled BSDF of its tree, or None."""
    reading = _principled(material)
    return reading[0] if reading is not None else None


def _principled(material):
    """(node, its group nodes, notes on how it was found) or None; see ``principled_node``."""
    if material is None or material.node_tree is None or not compat.uses_nodes(material):
        return None
    sources = principled_sources(material)
    if not sources and renders_an_output(material):
        return None  # Cycles renders what reaches the active output: no scattering node does
    if not sources:  # no output node at all: the tree's Principled BSDF, said so
        node = next((n for n in material.node_tree.nodes if n.bl_idname == PRINCIPLED), None)
        if node is None:
            return None
        return node, (), [f"Principled BSDF {node.name!r} does not reach the material output; read as it is"]

    def scatters(src) -> bool:
        socket = src.node.inputs.get("Subsurface Weight" if src.node.bl_idname == PRINCIPLED else "Scale")
        return socket is not None and (socket.is_linked or socket.default_value > 0)

    ranked = sorted(sources, key=lambda s: (not scatters(s), -(s.share if s.share is not None else 0.5)))
    best = ranked[0]
    notes = []
    if best.groups or len(sources) > 1 or best.share != 1.0:
        share = "a share set per pixel" if best.share is None else f"{best.share:.3g} of the surface"
        route = " > ".join(best.path[:-1]) or "the output"
        notes.append(f"{best.node.bl_rna.name} {best.node.name!r} reached through {route} ({share})")
    others = [s for s in ranked[1:] if scatters(s)]
    if others:
        names = ", ".join(repr(s.node.name) for s in others)
        notes.append(
            f"also scattering: Principled BSDF {names}; its inputs are not read (the passes' Diffuse Color carries"
            " each one's share)"
        )
    return best.node, best.groups, notes


@dataclasses.dataclass
class MaterialReading:
    """What ``read_material`` found: the description (None when the material has no Principled
    BSDF), how each subsurface input was read (one line each) and what could not be followed."""

    sss: MaterialSSS | None
    inputs: list[str]
    notes: list[str]


def _fmt(value) -> str:
    if isinstance(value, (tuple, list)):
        return "(" + ", ".join(f"{float(v):.4g}" for v in value) + ")"
    return f"{float(value):.4g}"


def read_material(material, index: int) -> MaterialReading:
    """``material``'s subsurface inputs as Cycles reads them where they are constants: typed in,
    or a Value or RGB node's through reroutes and group sockets (``shader_graph.input_value``).
    An input linked to anything else (a texture, an attribute, a Math node) is read at its
    socket's own value, said in ``notes``; a linked Subsurface Weight whose socket holds 0 is read
    as 1 (the material scatters wherever the link gives more than 0)."""
    found = _principled(material)
    if found is None:
        return MaterialReading(None, [], [])
    node, groups, notes = found
    notes = list(notes)
    lines: list[str] = []
    values: dict[str, Any] = {}
    per_pixel: list[str] = []
    if node.bl_idname == SUBSURFACE:
        values["subsurface_weight"] = 1.0
        lines.append(f"{node.bl_rna.name} {node.name!r}: its closure is the subsurface scattering (weight 1)")
    for key, socket_name in _input_names(node).items():
        socket = node.inputs.get(socket_name)
        if socket is None:
            continue  # e.g. Subsurface IOR exists only for the Skin method
        value, how = input_value(socket, groups)
        vector = key in ("subsurface_radius", "base_color")
        if value is not None:
            try:
                value = tuple(float(v) for v in value)[:3] if vector else float(value)
            except TypeError:  # a single number for a colour or vector: the same three times
                value = (float(value),) * 3 if vector else None
            if value is None:
                how += " (a colour read as a number: cannot tell how Cycles converts it)"
        if value is None:
            own = socket.default_value
            if vector:
                value = tuple(float(v) for v in own)[:3]
            else:  # a linked Weight of 0 in its socket: the link gives more than 0 somewhere
                value = 1.0 if key == "subsurface_weight" and float(own) <= 0 else float(own)
            aov = INPUT_AOVS.get(key)
            if aov is not None and socket.is_linked:
                per_pixel.append(key)
                notes.append(
                    f"{socket_name} {how}: read per pixel from the render (shader AOV {aov.name!r}); "
                    f"{_fmt(value)} until the passes are read"
                )
                lines.append(f"{socket_name}: {how}; read per pixel from the render (shader AOV {aov.name!r})")
            else:
                notes.append(f"{socket_name} {how}: not followed per pixel; {_fmt(value)} used instead")
                lines.append(f"{socket_name}: {how}; read as {_fmt(value)}")
        else:
            lines.append(f"{socket_name}: {how}, {_fmt(value)}")
        if key == "subsurface_weight" and value > 1.0:  # a mix factor: Cycles' closure clamps it to 1
            notes.append(f"{socket_name} reads {_fmt(value)}; Cycles clamps it to 1, and so does SSS Lab")
            value = 1.0
        values[key] = value
    base = values.pop("base_color")
    sss = MaterialSSS(
        index=index,
        name=material.name,
        method=compat.subsurface_method(node),
        base_color=tuple(min(float(c), 1.0) for c in base),
        fit=read_fit(material),
        notes=tuple(notes),
        per_pixel=tuple(per_pixel),
        **values,
    )
    return MaterialReading(sss, lines, notes)


def input_sockets(material, keys) -> list[tuple[str, Any]]:
    """(key, the input socket) of ``material``'s scattering node for each of ``keys`` (fields of
    ``MaterialSSS``, as ``MaterialSSS.per_pixel`` lists them) that the node has: where the passes
    render takes a per-pixel input from."""
    found = _principled(material)
    if found is None:
        return []
    node = found[0]
    names = _input_names(node)
    return [(k, node.inputs[names[k]]) for k in keys if k in names and names[k] in node.inputs]


def material_sss(material, index: int) -> MaterialSSS | None:
    """The subsurface inputs of ``material``'s Principled BSDF, or None if it has none
    (``read_material``)."""
    return read_material(material, index).sss


def scene_materials(scene) -> list:
    """Materials used by the visible mesh objects that the scene renders, in name order: those of
    their material slots, and those their evaluated geometry carries (a Geometry Nodes Set
    Material node assigns materials that no slot names; Cycles renders them). The geometry is
    the view layer's evaluation, of the objects whose Geometry Nodes modifiers render: a modifier
    shown in renders but hidden in the viewport is not evaluated there, and its materials are missed."""
    found = {}
    meshes = []
    for obj in scene.objects:
        if obj.type != "MESH" or obj.hide_render:
            continue
        meshes.append(obj)
        for slot in obj.material_slots:
            if slot.material is not None:
                found[slot.material.name] = slot.material
    evaluated = [obj for obj in meshes if any(m.type == "NODES" and m.show_render for m in obj.modifiers)]
    if evaluated:
        depsgraph = _depsgraph(scene)
        for obj in evaluated:
            data = getattr(obj.evaluated_get(depsgraph), "data", None)
            for material in getattr(data, "materials", ()) or ():
                if material is not None:
                    original = material.original
                    found[original.name] = original
    return [found[name] for name in sorted(found)]


def _depsgraph(scene):
    """The evaluated dependency graph of ``scene``'s view layer (the context's when it shows the scene)."""
    import bpy

    if bpy.context.scene == scene and bpy.context.view_layer is not None:
        return bpy.context.evaluated_depsgraph_get()
    layer = scene.view_layers[0]
    layer.depsgraph.update()
    return layer.depsgraph


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
