"""The one place that knows how Blender versions differ.

SSS Lab targets Blender 5.2 LTS; Blender 4.5 LTS is next. Every call whose spelling changed
between them goes through a function here, so that supporting another version means editing
this module alone. Only bpy-facing code imports it (core never does).
"""

from __future__ import annotations

import bpy

#: Oldest Blender this module knows how to drive (blender_manifest.toml says the same).
MIN_VERSION = (5, 2, 0)


def blender_version() -> tuple[int, int, int]:
    return tuple(bpy.app.version)


def is_supported() -> bool:
    return blender_version() >= MIN_VERSION


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
