"""Shader nodes of the thickness bake: the temporary bake material, and the nodes that wire a
baked map into a material's thickness AOV (``blender.bake`` explains both)."""

from __future__ import annotations

import bpy

from ..core.scene.thickness import BakeSettings
from . import compat
from .state import SceneState
from .stored import thickness_metadata

#: Names of the nodes SSS Lab adds to materials.
NODE_NAME = "SSS Lab Thickness"
NODE_UV = "SSS Lab Thickness UV"
NODE_AOV = "SSS Lab Thickness AOV"


_TMP_MATERIAL = "SSS Lab thickness bake (temporary)"


def bake_material(s: BakeSettings, node_samples: int):
    """A new temporary material that emits the Ambient Occlusion node's inside AO (inverted for
    the translucency convention), with an empty Image node for the bake's target."""
    mat = bpy.data.materials.new(_TMP_MATERIAL)
    compat.ensure_node_tree(mat)
    tree = mat.node_tree
    tree.nodes.clear()
    ao = tree.nodes.new("ShaderNodeAmbientOcclusion")
    ao.name = "AO"
    ao.inside = True
    ao.only_local = s.only_local
    ao.samples = node_samples
    emit = tree.nodes.new("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = 1.0
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    value = ao.outputs["AO"]
    if s.convention == "translucency":
        invert = tree.nodes.new("ShaderNodeMath")
        invert.operation = "SUBTRACT"
        invert.inputs[0].default_value = 1.0
        tree.links.new(value, invert.inputs[1])
        value = invert.outputs[0]
    tree.links.new(value, emit.inputs["Color"])
    tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    image_node = tree.nodes.new("ShaderNodeTexImage")
    image_node.name = "Image"
    return mat


def use_material(st: SceneState, obj, material) -> None:
    """Give every face of ``obj`` the bake material, for the duration of ``st``."""
    if len(obj.material_slots) == 0:
        obj.data.materials.append(material)
        st.on_restore(lambda: compat.remove_last_material_slot(obj))
        return
    for slot in obj.material_slots:
        st.set(slot, "material", material)


def result_image(mesh, s: BakeSettings):
    """(image, created): the image the previous bake of this mesh made, emptied and resized, or
    a new float image (linear, Non-Color)."""
    name = f"{mesh.name}_thickness"
    image = bpy.data.images.get(name)
    created = None
    if image is not None and image.library is None and thickness_metadata(image) is not None:
        image.source = "GENERATED"
        image.generated_type = "BLANK"
        image.use_generated_float = True
        image.generated_width = image.generated_height = s.resolution_px
        image.generated_color = (0.0, 0.0, 0.0, 1.0)
    else:
        image = created = bpy.data.images.new(name, s.resolution_px, s.resolution_px, alpha=False, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    return image, created


def _node(tree, name: str, bl_idname: str, location):
    node = tree.nodes.get(name)
    if node is not None and node.bl_idname != bl_idname:
        tree.nodes.remove(node)
        node = None
    if node is None:
        node = tree.nodes.new(bl_idname)
        node.name = name
        node.location = location
    node.label = name
    return node


def add_map_nodes(mat, s: BakeSettings, image, uv_map: str) -> str:
    """Add (or update) the nodes that read the map and feed the thickness AOV; returns a
    warning or ''."""
    compat.ensure_node_tree(mat)
    tree = mat.node_tree
    output = tree.get_output_node("CYCLES") or tree.get_output_node("ALL")
    x, y = (output.location.x, output.location.y - 320.0) if output is not None else (0.0, -320.0)
    if s.target == "attribute":
        old_uv = tree.nodes.get(NODE_UV)
        if old_uv is not None:
            tree.nodes.remove(old_uv)
        src = _node(tree, NODE_NAME, "ShaderNodeAttribute", (x - 400, y))
        src.attribute_type = "GEOMETRY"
        src.attribute_name = s.attribute_name
        socket = src.outputs["Fac"]
    else:
        uv = _node(tree, NODE_UV, "ShaderNodeUVMap", (x - 640, y))
        uv.uv_map = uv_map
        src = _node(tree, NODE_NAME, "ShaderNodeTexImage", (x - 400, y))
        src.image = image
        src.interpolation = "Linear"
        tree.links.new(uv.outputs["UV"], src.inputs["Vector"])
        socket = src.outputs["Color"]
    src.label = f"{NODE_NAME} ({s.convention})"
    foreign = [
        n
        for n in tree.nodes
        if n.bl_idname == "ShaderNodeOutputAOV" and n.name != NODE_AOV and n.aov_name == s.aov_name
    ]
    if foreign:
        old = tree.nodes.get(NODE_AOV)
        if old is not None:
            tree.nodes.remove(old)
        return f"material {mat.name!r} already writes the AOV {s.aov_name!r}: the map was added but not connected"
    aov = _node(tree, NODE_AOV, "ShaderNodeOutputAOV", (x - 160, y))
    aov.aov_name = s.aov_name
    tree.links.new(socket, aov.inputs["Value"])
    return ""
