"""Small helpers for building compositor node groups from Python (shared by the builders).

A builder owns its node group: ``ensure_group`` finds or creates it, brings its interface to
the wanted sockets (existing sockets are kept, so links and values on the group's instances
survive a rebuild) and empties it; ``Graph`` then adds nodes with one-line arithmetic.
Nothing here deletes a data-block the builders did not create.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import bpy
import numpy as np

from ..blender import compat

#: Custom property on a node group / image holding what SSS Lab built it from.
META_KEY = "sss_lab"

_SOCKET_TYPES = {
    "FLOAT": "NodeSocketFloat",
    "COLOR": "NodeSocketColor",
    "VECTOR": "NodeSocketVector",
    "MENU": "NodeSocketMenu",
}


@dataclass(frozen=True)
class Socket:
    """One socket of a group's interface.

    ``kind``: FLOAT, COLOR, VECTOR or MENU; ``default``: a number, an RGBA/XYZ tuple or, for a
    menu, the entry's name (the entries are ``items``).
    """

    name: str
    kind: str
    default: object = None
    description: str = ""
    min: float | None = None
    max: float | None = None
    items: tuple[str, ...] = ()
    subtype: str = ""


@dataclass
class Interface:
    inputs: list[Socket] = field(default_factory=list)
    outputs: list[Socket] = field(default_factory=list)


def _sockets(group, in_out: str) -> list:
    return [i for i in group.interface.items_tree if i.item_type == "SOCKET" and i.in_out == in_out]


def _sync_interface(group, wanted: list[Socket], in_out: str) -> None:
    """Make the group's ``in_out`` sockets exactly ``wanted``, in order, keeping matching ones."""
    interface = group.interface
    keep = set()
    for spec in wanted:
        kind = _SOCKET_TYPES[spec.kind]
        existing = next((s for s in _sockets(group, in_out) if s.name == spec.name), None)
        if existing is not None and existing.socket_type != kind:
            interface.remove(existing)
            existing = None
        if existing is None:
            existing = interface.new_socket(spec.name, in_out=in_out, socket_type=kind)
        keep.add(existing.identifier)
        existing.description = spec.description
        if spec.subtype and hasattr(existing, "subtype"):
            existing.subtype = spec.subtype
        if spec.min is not None:
            existing.min_value = spec.min
        if spec.max is not None:
            existing.max_value = spec.max
        if spec.default is not None and spec.kind != "MENU" and in_out == "INPUT":
            existing.default_value = spec.default
    for s in _sockets(group, in_out):
        if s.identifier not in keep:
            interface.remove(s)
    # Order: outputs and inputs are numbered separately; move each to its place among its kind.
    for index, spec in enumerate(wanted):
        current = _sockets(group, in_out)
        item = next(s for s in current if s.name == spec.name)
        if current.index(item) != index:
            interface.move(item, current[index].position)


def ensure_group(name: str, interface: Interface, meta: dict):
    """The compositor node group ``name`` with exactly ``interface``, emptied for a rebuild.

    A data-block of that name that is not a compositor node group is an error, not replaced.
    """
    group = bpy.data.node_groups.get(name)
    if group is None:
        group = bpy.data.node_groups.new(name, "CompositorNodeTree")
    elif group.bl_idname != "CompositorNodeTree":
        raise ValueError(f"node group {name!r} exists and is a {group.bl_idname}, not a compositor node group")
    _sync_interface(group, interface.inputs, "INPUT")
    _sync_interface(group, interface.outputs, "OUTPUT")
    group.nodes.clear()
    group[META_KEY] = meta
    return group


def set_menu_defaults(group, interface: Interface) -> None:
    """Menu sockets get their entries from the Menu Switch they feed, so their defaults are set
    once the nodes are linked."""
    for spec in interface.inputs:
        if spec.kind == "MENU" and spec.default is not None:
            socket = next(s for s in _sockets(group, "INPUT") if s.name == spec.name)
            socket.default_value = spec.default


def read_meta(group) -> dict:
    """The build parameters stored on a group (lists for tuples), or {}."""
    value = group.get(META_KEY) if group is not None else None
    if value is None:
        return {}
    return value.to_dict() if hasattr(value, "to_dict") else dict(value)


def ensure_image(name: str, pixels: np.ndarray, owner: str):
    """A float image ``name`` holding ``pixels`` ((rows, cols, 3), row 0 at the top), packed
    into the .blend file (float32 OpenEXR) so that it survives save and reload.

    An existing image of that name is reused only if SSS Lab made it for ``owner``; otherwise
    this raises instead of overwriting someone else's image.
    """
    arr = np.asarray(pixels, dtype=np.float32)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    rows, cols, channels = arr.shape
    rgba = np.zeros((rows, cols, 4), np.float32)
    rgba[..., :channels] = arr
    # Alpha: a delta at the centre, so that the alpha channel passes through unchanged.
    rgba[rows // 2, cols // 2, 3] = 1.0
    image = bpy.data.images.get(name)
    if image is not None and image.get(META_KEY, {}).get("owner") != owner:
        raise ValueError(f"image {name!r} exists and was not made by SSS Lab for {owner!r}; rename it")
    if image is not None and tuple(image.size) != (cols, rows):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, cols, rows, alpha=True, float_buffer=True, is_data=True)
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(rgba[::-1].ravel())  # Blender's rows run bottom to top
    image.pack()
    image.use_fake_user = False
    image[META_KEY] = {"owner": owner}
    return image


def image_pixels(image) -> np.ndarray:
    """An image's pixels as (rows, cols, 4) float32, row 0 at the top."""
    cols, rows = image.size
    flat = np.empty(rows * cols * 4, np.float32)
    image.pixels.foreach_get(flat)
    return flat.reshape(rows, cols, 4)[::-1]


class Graph:
    """Adds nodes to a group with arithmetic helpers; operands are sockets or constants."""

    def __init__(self, group):
        self.group = group
        self.tree = group
        self.input = group.nodes.new("NodeGroupInput")
        self.output = group.nodes.new("NodeGroupOutput")
        self._column = 1
        self._row = 0
        self._menus: dict = {}

    # -- placement --------------------------------------------------------------------------
    def column(self) -> None:
        """Start a new column of nodes (left to right reads as the order of computation)."""
        self._column += 1
        self._row = 0

    def _place(self, node, label: str = "") -> None:
        node.location = (self._column * 220.0, -self._row * 170.0)
        self._row += 1
        if label:
            node.label = label
        self.output.location = ((self._column + 1) * 220.0, 0.0)
        self.input.location = (0.0, 0.0)

    def node(self, bl_idname: str, label: str = ""):
        node = self.group.nodes.new(bl_idname)
        self._place(node, label)
        return node

    # -- wiring -----------------------------------------------------------------------------
    def inp(self, name: str):
        return self.input.outputs[name]

    def out(self, name: str, value) -> None:
        self.connect(value, self.output.inputs[name])

    def connect(self, value, socket) -> None:
        if isinstance(value, bpy.types.NodeSocket):
            self.group.links.new(value, socket)
        elif isinstance(value, (tuple, list)):
            v = tuple(float(x) for x in value)
            n = len(socket.default_value)
            socket.default_value = (v + (1.0,) * n)[:n]
        else:
            socket.default_value = value

    # -- float math -------------------------------------------------------------------------
    def math(self, op: str, a, b=None, c=None, label: str = ""):
        node = self.node("ShaderNodeMath", label)
        node.operation = op
        node.use_clamp = False
        for socket, value in zip(node.inputs, (a, b, c), strict=True):
            if value is not None:
                self.connect(value, socket)
        return node.outputs[0]

    def add(self, a, b, label=""):
        return self.math("ADD", a, b, label=label)

    def sub(self, a, b, label=""):
        return self.math("SUBTRACT", a, b, label=label)

    def mul(self, a, b, label=""):
        return self.math("MULTIPLY", a, b, label=label)

    def div(self, a, b, label=""):
        return self.math("DIVIDE", a, b, label=label)

    def max(self, a, b, label=""):
        return self.math("MAXIMUM", a, b, label=label)

    def clamp01(self, a, label=""):
        node = self.node("ShaderNodeClamp", label)
        node.clamp_type = "MINMAX"
        self.connect(a, node.inputs["Value"])
        node.inputs["Min"].default_value = 0.0
        node.inputs["Max"].default_value = 1.0
        return node.outputs[0]

    # -- vector / colour math (colours are converted to vectors: RGB, alpha dropped) ---------
    def vmath(self, op: str, a, b=None, scale=None, label: str = ""):
        node = self.node("ShaderNodeVectorMath", label)
        node.operation = op
        vectors = [s for s in node.inputs if s.type == "VECTOR"]
        for socket, value in zip(vectors, (a, b), strict=False):
            if value is not None:
                self.connect(value, socket)
        if scale is not None:
            self.connect(scale, node.inputs["Scale"])
        return node.outputs["Value"] if op in ("DOT_PRODUCT", "LENGTH", "DISTANCE") else node.outputs["Vector"]

    def vadd(self, a, b, label=""):
        return self.vmath("ADD", a, b, label=label)

    def vsub(self, a, b, label=""):
        return self.vmath("SUBTRACT", a, b, label=label)

    def vmul(self, a, b, label=""):
        return self.vmath("MULTIPLY", a, b, label=label)

    def vscale(self, a, s, label=""):
        return self.vmath("SCALE", a, scale=s, label=label)

    def gray(self, value, label=""):
        """A float as an RGB vector (v, v, v)."""
        node = self.node("ShaderNodeCombineXYZ", label)
        for socket in node.inputs:
            self.connect(value, socket)
        return node.outputs[0]

    # -- selection --------------------------------------------------------------------------
    def menu(self, data_type: str, menu_socket, options: dict, label: str = ""):
        """The value of ``options`` (entry -> value) picked by the menu socket ``menu_socket``.

        One Menu Switch per menu socket turns the entry into its index, and an Index Switch per
        use picks the value: a menu socket linked to two Menu Switches has no entries at all
        (Blender sees two menus that may differ), so it must feed exactly one.
        """
        key = (menu_socket.node.name, menu_socket.identifier)
        if key not in self._menus:
            items = tuple(options)
            node, menu, inputs, output = compat.new_menu_switch(self.tree, "INT", items)
            self._place(node, f"{menu_socket.name} index")
            self.connect(menu_socket, menu)
            for i, name in enumerate(items):
                inputs[name].default_value = i
            self._menus[key] = (items, output)
        items, index = self._menus[key]
        if tuple(options) != items:
            raise ValueError(f"menu {menu_socket.name!r}: entries {tuple(options)} differ from {items}")
        node = self.node("GeometryNodeIndexSwitch", label)
        node.data_type = data_type
        while len([s for s in node.inputs[1:] if s.type != "CUSTOM"]) < len(items):
            node.index_switch_items.new()
        self.connect(index, node.inputs["Index"])
        values = [s for s in node.inputs[1:] if s.type != "CUSTOM"]
        for socket, value in zip(values, options.values(), strict=True):
            self.connect(value, socket)
        return node.outputs[0]

    # -- images and convolution ------------------------------------------------------------
    def image(self, image, label: str = ""):
        node = self.node("CompositorNodeImage", label)
        node.image = image
        return node.outputs["Image"]

    def convolve(self, value, kernel_image, label: str = ""):
        """Convolve ``value`` (a colour) with a per-channel kernel image (Color kernel, not
        normalized: the kernels of core.optics.kernel_images sum to one per channel)."""
        kernel = self.image(kernel_image, label=f"{label} kernel" if label else "")
        node, image_in, kernel_in, output = compat.new_convolve(self.tree, color_kernel=True, normalize=False)
        self._place(node, label)
        self.connect(value, image_in)
        self.group.links.new(kernel, kernel_in)
        return output

    def blur(self, value, size: int, label: str = ""):
        """``value`` (RGBA) through a Blur node's Gaussian of integer ``size`` (all four channels)."""
        node, image_in, output = compat.new_gaussian_blur(self.tree, size)
        self._place(node, label)
        self.connect(value, image_in)
        return output

    def with_alpha(self, rgb, alpha, label: str = ""):
        """An RGBA colour from an RGB vector and a float alpha."""
        node, image_in, alpha_in, output = compat.new_set_alpha(self.tree)
        self._place(node, label)
        self.connect(rgb, image_in)
        self.connect(alpha, alpha_in)
        return output

    def alpha(self, value, label: str = ""):
        """The alpha of an RGBA colour."""
        node = self.node("CompositorNodeSeparateColor", label)
        self.connect(value, node.inputs["Image"])
        return node.outputs["Alpha"]

    def add_keep_alpha(self, image, rgb, label: str = "Image + SSS"):
        """``image`` + ``rgb`` with the image's alpha kept (vector math drops alpha)."""
        sep = self.node("CompositorNodeSeparateColor")
        self.connect(image, sep.inputs[0])
        xyz = self.node("ShaderNodeSeparateXYZ")
        self.connect(self.vadd(image, rgb), xyz.inputs[0])
        comb = self.node("CompositorNodeCombineColor", label)
        for i in range(3):
            self.connect(xyz.outputs[i], comb.inputs[i])
        self.connect(sep.outputs[3], comb.inputs[3])
        return comb.outputs[0]
