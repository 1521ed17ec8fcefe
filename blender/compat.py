"""The one place that knows how Blender versions differ.

SSS Lab runs on Blender 5.2 and on 4.5 LTS (docs/blender45.md). Every call whose spelling or
meaning changed between them goes through a function here, so that supporting another version means editing
this module alone. Only bpy-facing code imports it (core never does).
"""

from __future__ import annotations

import bpy

from ..core.base.errors import SSSLabError
from ..core.scene.passes import PASSES

#: Oldest Blender this module knows how to drive (blender_manifest.toml says the same).
MIN_VERSION = (4, 5, 0)


def blender_version() -> tuple[int, int, int]:
    return tuple(bpy.app.version)


def is_supported() -> bool:
    return blender_version() >= MIN_VERSION


# --- Subsurface methods -----------------------------------------------------------------------
# The scene description and core/ name a method by its Cycles convention in Blender 5.x's words
# (core.scene.scene.SUBSURFACE_METHODS). 4.5's "Random Walk" is what 5.x calls "Random Walk (Legacy)"
# (mean free path = radius / 4 pi; 5.x converts it so when it opens a 4.5 file, and renders it
# alike: docs/blender45.md); 4.5 has no counterpart of 5.x's new "Random Walk".

#: This version's ``subsurface_method`` enum item -> the method's name in the scene description.
_METHOD_NAMES_45 = {"BURLEY": "BURLEY", "RANDOM_WALK": "RANDOM_WALK_LEGACY", "RANDOM_WALK_SKIN": "RANDOM_WALK_SKIN"}


def _method_names() -> dict[str, str]:
    if bpy.app.version >= (5, 0, 0):
        return {m: m for m in ("BURLEY", "RANDOM_WALK", "RANDOM_WALK_SKIN", "RANDOM_WALK_LEGACY")}
    return _METHOD_NAMES_45


def subsurface_methods() -> tuple[str, ...]:
    """The subsurface methods this Blender renders, as the scene description names them."""
    return tuple(_method_names().values())


def random_walk_method() -> str:
    """This Blender's newest random walk, as the scene description names it: ``RANDOM_WALK`` in
    5.x, ``RANDOM_WALK_LEGACY`` in 4.5 (whose Random Walk that is)."""
    return "RANDOM_WALK" if "RANDOM_WALK" in subsurface_methods() else "RANDOM_WALK_LEGACY"


def subsurface_method(bsdf) -> str:
    """The subsurface method of a Principled BSDF (``subsurface_method``) or a Subsurface
    Scattering node (``falloff``), as the scene description names it."""
    item = bsdf.falloff if bsdf.bl_idname == "ShaderNodeSubsurfaceScattering" else bsdf.subsurface_method
    return _method_names()[item]


def subsurface_method_item(method: str) -> str:
    """The ``subsurface_method`` enum item of this Blender for ``method`` (a scene-description
    name). Raises ValueError naming the methods this version has when it has no such method."""
    for item, name in _method_names().items():
        if name == method:
            return item
    raise ValueError(
        f"subsurface method {method!r}: Blender {bpy.app.version_string} has no such method; "
        f"expected one of: {', '.join(subsurface_methods())}"
    )


def eevee_engine() -> str:
    """EEVEE's ``render.engine`` identifier: ``BLENDER_EEVEE`` in 5.x, ``BLENDER_EEVEE_NEXT`` in 4.5."""
    return "BLENDER_EEVEE" if bpy.app.version >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"


def set_thin_wall(bsdf, value: bool) -> None:
    """Set the Principled BSDF's "Thin Wall" input (5.x). 4.5 has no such input: its surfaces are
    always solid, which is what ``value`` False asks for; True there raises, naming the version."""
    socket = bsdf.inputs.get("Thin Wall")
    if socket is not None:
        socket.default_value = value
    elif value:
        raise RuntimeError(f"the Principled BSDF of Blender {bpy.app.version_string} has no Thin Wall input")


def set_multilayer_exr(image_settings, *, color_depth: str = "32") -> None:
    """Configure ``image_settings`` for a float32 multilayer EXR.

    5.x needs ``media_type`` set before ``file_format`` (the other order raises); 4.5 has no
    ``media_type``.
    """
    if hasattr(image_settings, "media_type"):
        image_settings.media_type = "MULTI_LAYER_IMAGE"
    image_settings.file_format = "OPEN_EXR_MULTILAYER"
    image_settings.color_depth = color_depth
    image_settings.exr_codec = "ZIP"


def exr_part_per_pass() -> bool:
    """Whether this Blender writes a multilayer EXR as one part per pass (5.x) rather than one
    part holding every channel (4.5; ``core.scene.exr`` reads both)."""
    return bpy.app.version >= (5, 0, 0)


def exr_pass_name(name: str) -> str:
    """The name this Blender gives render pass ``name`` (5.x's name, e.g. "Diffuse Direct") in a
    multilayer EXR and in an Image node's outputs: 4.5 uses the short names ("DiffDir")."""
    if bpy.app.version >= (5, 0, 0):
        return name
    info = PASSES.get(name)
    return info.short_name if info is not None and info.short_name else name


#: Image-format settings that ``set_multilayer_exr`` changes, in the order they must be restored.
_IMAGE_FORMAT_ATTRS = ("media_type", "file_format", "color_depth", "exr_codec")


def image_format_state(image_settings) -> dict:
    """The image-format settings ``set_multilayer_exr`` and ``set_single_image`` change, to put
    back with ``restore_image_format``."""
    return {a: getattr(image_settings, a) for a in _IMAGE_FORMAT_ATTRS if hasattr(image_settings, a)}


def restore_image_format(image_settings, state: dict) -> None:
    """Put back what ``image_format_state`` recorded. 5.x: ``media_type`` first, since changing
    it resets ``file_format`` (and a multilayer media type refuses any other file format)."""
    for attr in _IMAGE_FORMAT_ATTRS:
        if attr in state and getattr(image_settings, attr) != state[attr]:
            setattr(image_settings, attr, state[attr])


def set_single_image(image_settings, file_format: str, *, color_depth: str | None = None) -> None:
    """Configure ``image_settings`` for a single-layer image (PNG, EXR)."""
    if hasattr(image_settings, "media_type"):
        image_settings.media_type = "IMAGE"
    image_settings.file_format = file_format
    if color_depth is not None:
        image_settings.color_depth = color_depth


def compositor_tree(scene, *, create: bool = False):
    """The scene's compositor node tree, or None.

    5.x keeps it in ``scene.compositing_node_group`` (a CompositorNodeTree data-block);
    4.5 uses ``scene.node_tree`` behind ``scene.use_nodes``.
    """
    if hasattr(scene, "compositing_node_group"):
        tree = scene.compositing_node_group
        if tree is None and create:
            tree = bpy.data.node_groups.new(f"{scene.name} Compositor", "CompositorNodeTree")
            scene.compositing_node_group = tree
        return tree
    if create:
        scene.use_nodes = True
    return scene.node_tree


def uses_nodes(idblock) -> bool:
    """Whether a material or world shades with its node tree (always in 5.x, where
    ``use_nodes`` is deprecated; a flag in 4.5)."""
    if bpy.app.version >= (5, 0, 0):
        return idblock.node_tree is not None
    return bool(idblock.use_nodes)


def ensure_node_tree(idblock) -> None:
    """Give a material or world its node tree (5.x creates it; 4.5 needs ``use_nodes``)."""
    if bpy.app.version < (5, 0, 0) or idblock.node_tree is None:
        idblock.use_nodes = True


def multires_bake_switch(scene) -> tuple[object, str]:
    """Where the "bake from multires" switch lives: (owner, attribute) to set or record.

    5.x: ``scene.render.bake.use_multires``; 4.5: ``scene.render.use_bake_multires``."""
    bake = scene.render.bake
    if hasattr(bake, "use_multires"):
        return bake, "use_multires"
    return scene.render, "use_bake_multires"


def run_bake(*, target: str, margin: int | None = None, uv_layer: str = "") -> set:
    """Cycles' Emit bake of the selected objects into ``target`` (``VERTEX_COLORS``: the active
    colour attribute; ``IMAGE_TEXTURES``: the active Image Texture node of each material).

    Every option is passed to the operator, so the scene's bake settings are not consulted.
    Raises RuntimeError with Blender's message when the bake fails.
    """
    kwargs = {
        "type": "EMIT",
        "target": target,
        "save_mode": "INTERNAL",
        "use_clear": True,
        "use_selected_to_active": False,
        "use_cage": False,
        "use_split_materials": False,
    }
    if margin is not None:
        kwargs.update(margin=margin, margin_type="ADJACENT_FACES")
    if uv_layer:
        kwargs["uv_layer"] = uv_layer
    return bpy.ops.object.bake(**kwargs)


def save_float_image(image, filepath: str, file_format: str) -> None:
    """Write a float image to ``filepath``: ``OPEN_EXR`` as float32 (not half), ``PNG`` as 16
    bits per channel (what 5.x writes for a float buffer). The image's colour space is kept, so
    a Non-Color image is written linear."""
    image.file_format = file_format
    if file_format == "OPEN_EXR":
        image.use_half_precision = False
    image.filepath_raw = filepath
    image.save()


def remove_last_material_slot(obj) -> None:
    """Remove ``obj``'s last material slot from the object and its data (and so from every
    object sharing the data). Popping ``obj.data.materials`` alone leaves the object's own slot
    count behind, an empty slot; the operator removes both."""
    obj.active_material_index = len(obj.material_slots) - 1
    with bpy.context.temp_override(object=obj):
        bpy.ops.object.material_slot_remove()


# --- Compositor nodes (nodes/ builds its node groups through these) ---------------------------


class MissingFeature(SSSLabError, RuntimeError):
    """This Blender lacks something SSS Lab needs for the job; the message says what and what to
    use instead."""


def compositor_groups_missing() -> str | None:
    """Why this Blender cannot run SSS Lab's compositor node groups, or None when it can.

    The groups convolve with the Convolve node and choose options with Menu sockets in their
    interfaces; Blender 4.5's compositor has neither."""
    if hasattr(bpy.types, "CompositorNodeConvolve"):
        return None
    return (
        f"Blender {bpy.app.version_string.split()[0]} has no compositor Convolve node and no Menu sockets in "
        "compositor node groups, which SSS Lab's compositor node groups need (Blender 5.2 has both); "
        "use Render Passes and Apply instead (the same techniques in NumPy)"
    )


def require_compositor_groups() -> None:
    """Raise ``MissingFeature`` saying what this Blender lacks when it cannot run the groups."""
    reason = compositor_groups_missing()
    if reason is not None:
        raise MissingFeature(reason)


#: The node type of a node group instance inside a compositor tree.
COMPOSITOR_GROUP_NODE = "CompositorNodeGroup"


def new_convolve(tree, *, color_kernel: bool = True, normalize: bool = False):
    """A Convolve node set to a per-channel (Color) or single-channel (Float) kernel.

    5.x has the node's options as input sockets: the "Kernel Data Type" menu (a Float kernel
    image is read as its luminance) and the "Normalize Kernel" switch; the node has one
    "Kernel" input socket per data type. Returns (node, image input, kernel input, output).
    """
    node = tree.nodes.new("CompositorNodeConvolve")
    node.inputs["Kernel Data Type"].default_value = "Color" if color_kernel else "Float"
    node.inputs["Normalize Kernel"].default_value = normalize
    kind = "RGBA" if color_kernel else "VALUE"
    kernel = next(s for s in node.inputs if s.name == "Kernel" and s.type == kind)
    return node, node.inputs["Image"], kernel, node.outputs["Image"]


def new_gaussian_blur(tree, size: int):
    """A Blur node with the Gaussian filter at ``size`` pixels on both axes, separable, bounds not
    extended. 5.x has the filter as the "Type" menu socket; 4.5 as the ``filter_type`` property.
    Returns (node, image input, output)."""
    node = tree.nodes.new("CompositorNodeBlur")
    if "Type" in node.inputs:
        node.inputs["Type"].default_value = "Gaussian"
    else:
        node.filter_type = "GAUSS"
    node.inputs["Size"].default_value = (float(size), float(size))
    if "Separable" in node.inputs:
        node.inputs["Separable"].default_value = True
    return node, node.inputs["Image"], node.outputs["Image"]


def new_set_alpha(tree):
    """A Set Alpha node that replaces the image's alpha. Returns (node, image input, alpha input,
    output)."""
    node = tree.nodes.new("CompositorNodeSetAlpha")
    if "Type" in node.inputs:
        node.inputs["Type"].default_value = "Replace Alpha"
    else:
        node.mode = "REPLACE_ALPHA"
    return node, node.inputs["Image"], node.inputs["Alpha"], node.outputs["Image"]


def new_menu_switch(tree, data_type: str, items: tuple[str, ...]):
    """A Menu Switch node with the menu entries ``items`` (5.x compositors have the Menu Switch
    of geometry nodes). Returns (node, menu input, {item: input socket}, output)."""
    node = tree.nodes.new("GeometryNodeMenuSwitch")
    node.data_type = data_type
    while len(node.enum_items) < len(items):
        node.enum_items.new(f"item {len(node.enum_items)}")
    while len(node.enum_items) > len(items):
        node.enum_items.remove(node.enum_items[-1])
    for entry, name in zip(node.enum_items, items, strict=True):
        entry.name = name
    values = [s for s in node.inputs[1:] if s.type != "CUSTOM"]
    return node, node.inputs["Menu"], dict(zip(items, values, strict=True)), node.outputs[0]


def compositor_result_socket(tree):
    """The input socket that receives a compositor tree's result, created if missing.

    5.x: the first colour output of the node group (a Group Output node), not a Composite node.
    """
    interface = tree.interface
    outputs = [i for i in interface.items_tree if i.item_type == "SOCKET" and i.in_out == "OUTPUT"]
    if not any(i.socket_type == "NodeSocketColor" for i in outputs):
        interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    node = next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput" and n.is_active_output), None)
    if node is None:
        node = next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"), None) or tree.nodes.new(
            "NodeGroupOutput"
        )
    return next(s for s in node.inputs if s.type == "RGBA")


def set_compositor_device(scene, device: str = "CPU") -> None:
    """Run the compositor on ``device`` ("CPU" or "GPU"; 5.x ``render.compositor_device``).
    Headless machines without a GPU context should use the CPU."""
    if hasattr(scene.render, "compositor_device"):
        scene.render.compositor_device = device
