"""Wire the technique node groups into a compositor tree, after a node that provides the passes.

``build_chain`` adds one group node per light (STA) or per scattering material (SSSS, Burley),
chained Image -> Image, with the passes taken by name from a ``source`` node: a Render Layers
node (``insert_chain``, for the compositor set-up: ``operators/compositing.py``) or an Image node
holding a multilayer EXR (the tests, the benchmark), whose outputs carry the same pass names.
Each node it adds is tagged with the custom property ``sss_lab``; ``remove_chain`` removes
exactly those and reconnects whatever read the chain's result to the chain's input, so the
user's own nodes are never deleted; ``uses_node_groups`` says whether a render runs them.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..blender import compat
from ..core.pipeline import mapping
from ..core.pipeline.fit_params import fitted
from ..core.scene.passes import THICKNESS
from ..core.scene.scene import SceneDescription
from ..core.techniques.registry import TECHNIQUES, check_technique
from ..core.techniques.sta.technique import TECHNIQUE as STA
from .burley import ensure_burley_group
from .ssss import ensure_ssss_group
from .sta import PARAM_SOCKETS as STA_PARAM_SOCKETS
from .sta import ensure_sta_group

#: Custom property on the nodes SSS Lab adds to a compositor tree (its value: the technique).
NODE_TAG = "sss_lab"

#: Group input -> pass name (Render Layers and multilayer-EXR Image nodes use the same names).
PASS_INPUTS = {
    "albedo": "Diffuse Color",
    "normal": "Normal",
    "position": "Position",
    "diffuse": "Diffuse Direct",
    "diffuse_indirect": "Diffuse Indirect",
}
INDEX_PASS = "Material Index"


@dataclass(frozen=True)
class ChainBuilder:
    """How one technique's node groups go into a compositor tree."""

    #: Passes its groups read, by their Blender 5.x names (``core/scene/passes.py``); ``THICKNESS``:
    #: the scene's thickness AOV. The mask needs the Material Index.
    passes: tuple[str, ...]
    #: True when it adds one group per material, each with its kernel at the material's fixed
    #: screen scale (``pixels_per_unit``); False for one group per light.
    per_material: bool
    #: ``add(tree, source, current, scene, options, pixels_per_unit, x, y, notes)``: adds the
    #: nodes after ``current`` and returns the new output socket.
    add: Callable
    #: Warnings for options the groups do not model, one line each.
    unmodelled: Callable[[Mapping], list[str]] = lambda options: []


def group_name(technique: str, material_name: str = "") -> str:
    """The node group of ``technique`` (a builder with one group per material: its own kernel)."""
    spec = TECHNIQUES.get_spec(technique)
    per_material = builder(spec.name).per_material
    return f"SSS Lab {spec.label}" + (f" {material_name}" if material_name and per_material else "")


def _tag(node, technique: str, name: str, location) -> None:
    node[NODE_TAG] = technique
    node.name = name
    node.label = name
    node.location = location


def _tagged(tree) -> list:
    return [n for n in tree.nodes if NODE_TAG in n.keys()]


def _pass(source, name: str):
    socket = source.outputs.get(name)
    if socket is None or not socket.enabled:
        raise ValueError(
            f"{source.name!r} has no {name!r} output; switch the pass on "
            "(View Layer Properties > Passes) or render the passes with SSS Lab"
        )
    return socket


def _mask(tree, source, indices: list[int], technique: str, location):
    """1 where the Material Index is one of ``indices`` (Compare nodes, summed)."""
    index = _pass(source, INDEX_PASS)
    total = None
    for k, value in enumerate(indices):
        node = tree.nodes.new("ShaderNodeMath")
        _tag(node, technique, f"SSS Lab mask {value}", (location[0], location[1] - 120 * k))
        node.operation = "COMPARE"
        tree.links.new(index, node.inputs[0])
        node.inputs[1].default_value = float(value)
        node.inputs[2].default_value = 0.5
        if total is None:
            total = node.outputs[0]
        else:
            add = tree.nodes.new("ShaderNodeMath")
            _tag(add, technique, f"SSS Lab mask sum {value}", (location[0] + 160, location[1] - 120 * k))
            add.operation = "ADD"
            tree.links.new(total, add.inputs[0])
            tree.links.new(node.outputs[0], add.inputs[1])
            total = add.outputs[0]
    return total


def _set(node, name: str, value) -> None:
    socket = node.inputs[name]
    if isinstance(value, (tuple, list, np.ndarray)):
        v = tuple(float(x) for x in value)
        n = len(socket.default_value)
        socket.default_value = (v + (1.0,) * n)[:n]
    else:
        socket.default_value = value


def build_chain(
    tree,
    source,
    *,
    image,
    technique: str,
    scene: SceneDescription,
    options: Mapping | None = None,
    pixels_per_unit: Mapping[int, float] | None = None,
    location=(400.0, 0.0),
) -> tuple[object, list[str]]:
    """Add ``technique``'s group nodes to ``tree``; returns (the result's output socket, notes).

    ``image``: the output socket the SSS is composited onto (Render Layers "Image", or an EXR's
    "Combined"); ``source``: the node whose outputs hold the passes. ``scene``: the scene
    description (camera, lights, the subsurface materials with their pass indices).
    ``options``: technique parameters under ``core``'s names (STA: distortion, power, scale,
    ambient; SSSS: kernel_type, n_taps, ...; all: albedo_mode); missing ones keep the defaults.
    ``pixels_per_unit``: material index -> the kernel's fixed screen scale (SSSS, Burley).
    Notes say what was left out and why (no lights, no screen scale for a material...).
    Raises ``compat.MissingFeature`` on a Blender without the nodes the groups need (4.5).
    """
    compat.require_compositor_groups()
    chain = builder(technique)
    options = dict(options or {})
    notes: list[str] = []
    materials = [m for m in scene.materials if m.scatters]
    x, y = location
    if not materials:
        notes.append("no subsurface material in the scene description: nothing to add")
        return image, notes
    current = chain.add(tree, source, image, scene, options, dict(pixels_per_unit or {}), x, y, notes)
    return current, notes


def _add_sta(tree, source, current, scene, options, pixels_per_unit, x, y, notes):
    """One STA group per light with energy, chained; the mask covers every subsurface material."""
    materials = [m for m in scene.materials if m.scatters]
    group = ensure_sta_group()
    mask = _mask(tree, source, [m.index for m in materials], "sta", (x, y - 300))
    lights = [light for light in scene.lights if light.energy > 0]
    if not lights:
        notes.append("STA: the scene has no light with energy > 0: nothing to add")
    for m in materials:
        if fitted(m.fit, "sta"):
            notes.append(
                f"{m.name}: its fitted STA scale is not applied by the node group (one scale for every material,"
                " the panel's); Apply applies it"
            )
    cam = scene.camera
    for k, light in enumerate(lights):
        node = tree.nodes.new(compat.COMPOSITOR_GROUP_NODE)
        node.node_tree = group
        _tag(node, "sta", f"SSS Lab STA {light.name or k}", (x + 350 + 260 * k, y))
        tree.links.new(current, node.inputs["Image"])
        for name in ("albedo", "normal", "position"):
            tree.links.new(_pass(source, PASS_INPUTS[name]), node.inputs[name])
        tree.links.new(_pass(source, scene.thickness_aov), node.inputs["thickness"])
        tree.links.new(mask, node.inputs["mask"])
        for socket in STA_PARAM_SOCKETS:
            if socket.name in options:
                _set(node, socket.name, float(options[socket.name]))
        node.inputs["thickness_convention"].default_value = scene.thickness_convention
        node[LIGHT_KEY] = light.name  # what ``follow_scene`` updates it from, frame by frame
        _set_light(node, light, cam)
        current = node.outputs["Image"]
    return current


#: Custom property of an STA group node: the name of the light it models.
LIGHT_KEY = "sss_lab_light"
#: Custom properties of an SSSS or Burley group node: its material's pass index and the screen
#: scale its kernel was built for (pixels per scene unit).
MATERIAL_KEY = "sss_lab_material"
SCALE_KEY = "sss_lab_pixels_per_unit"
#: How far a material's screen scale may move from the one its kernel was built for before
#: ``follow_scene`` says so (the kernel's footprint in pixels is off by as much).
SCALE_TOLERANCE = 0.05


def _set_light(node, light, cam) -> None:
    node.inputs["light_type"].default_value = light.type
    _set(node, "light_direction", light.direction)
    _set(node, "light_position", light.position)
    _set(node, "light_color", light.color)
    _set(node, "light_energy", float(light.energy))
    _set(node, "light_spot_size", float(light.spot_size))
    _set(node, "light_spot_blend", float(light.spot_blend))
    node.inputs["camera_type"].default_value = cam.type
    _set(node, "camera_position", cam.position)
    _set(node, "camera_forward", cam.forward)


def follow_scene(tree, scene: SceneDescription, pixels_per_unit: Mapping[int, float] | None = None) -> list[str]:
    """Bring the groups of ``tree`` to the scene as it is now (``scene``: its description at this
    frame): each STA group takes its light's and the camera's current values (a light gone or
    without energy adds nothing); an SSSS or Burley group's kernel is built for a screen scale,
    so where a material's ``pixels_per_unit`` moved more than ``SCALE_TOLERANCE`` from it a note
    says so. Returns the notes (none when everything followed)."""
    notes = []
    lights = {light.name: light for light in scene.lights}
    for node in _tagged(tree):
        if LIGHT_KEY in node.keys():
            light = lights.get(node[LIGHT_KEY])
            if light is None or light.energy <= 0:
                _set(node, "light_energy", 0.0)
                notes.append(f"STA: light {node[LIGHT_KEY]!r} is gone or has no energy at this frame: it adds nothing")
                continue
            _set_light(node, light, scene.camera)
        elif SCALE_KEY in node.keys() and pixels_per_unit is not None:
            built, now = float(node[SCALE_KEY]), pixels_per_unit.get(int(node[MATERIAL_KEY]))
            if now is not None and built > 0 and abs(now / built - 1.0) > SCALE_TOLERANCE:
                notes.append(
                    f"{node.name}: its kernel was built for {built:.4g} pixels per unit, the material is at"
                    f" {now:.4g} now (the camera or the object moved): set up the compositor again at this"
                    " frame, or use Apply, for the right width"
                )
    return notes


def _sta_unmodelled(options: Mapping) -> list[str]:
    if options.get("falloff", STA.defaults["falloff"]) == STA.defaults["falloff"]:
        return []
    return [
        "the STA node group uses the paper's falloff (the map for all channels); the Burley"
        " transmission falloff exists only in Apply (NumPy)"
    ]


def _scatter_adder(technique: str, ensure: Callable) -> Callable:
    """The ``add`` of a technique with one group per material built by ``ensure(name=,
    pixels_per_unit=, d_su=, **kernel options)``: the options ``ensure`` takes are passed on."""
    taken = set(inspect.signature(ensure).parameters) - {"name", "pixels_per_unit", "d_su"}

    def add(tree, source, current, scene, options, pixels_per_unit, x, y, notes):
        kernel_options = {k: options[k] for k in taken if options.get(k) is not None}
        for k, material in enumerate(m for m in scene.materials if m.scatters):
            if material.index not in pixels_per_unit:
                notes.append(f"{material.name}: no screen scale (no visible object in front of the camera): left out")
                continue
            d_su = mapping.burley_d(material, mapping=options.get("mapping"))
            fit = fitted(material.fit, technique)
            if "d_scale" in fit:
                d_su = tuple(v * float(fit["d_scale"]) for v in d_su)
                notes.append(
                    f"{material.name}: the {technique} node group uses its fitted width (x{fit['d_scale']:.3g})"
                )
            if "gain" in fit:
                gain = ", ".join(f"{float(g):.3g}" for g in fit["gain"])
                notes.append(
                    f"{material.name}: its fitted gain ({gain}) is not applied by the {technique} node group;"
                    " Apply applies it"
                )
            if material.per_pixel:
                # The group's kernel is built once from numbers; the AOVs it would need per pixel
                # are not rendered for the compositor.
                inputs = ", ".join(k.replace("_", " ") for k in material.per_pixel)
                notes.append(
                    f"{material.name}: {inputs} linked to a texture or node: the {technique} node group uses the "
                    "sockets' values (d " + "/".join(f"{v:.3g}" for v in d_su) + "); Render Passes and Apply read"
                    " them per pixel"
                )
            if material.subsurface_weight < 1.0:
                notes.append(
                    f"{material.name}: Subsurface Weight {material.subsurface_weight:.3g}: the {technique} node group"
                    " scatters all of the diffuse light; Apply mixes it by the weight as Cycles does"
                )
            name = group_name(technique, material.name)
            group = ensure(name=name, pixels_per_unit=pixels_per_unit[material.index], d_su=d_su, **kernel_options)
            node = tree.nodes.new(compat.COMPOSITOR_GROUP_NODE)
            node.node_tree = group
            _tag(node, technique, name, (x + 350 + 260 * k, y))
            node[MATERIAL_KEY], node[SCALE_KEY] = material.index, float(pixels_per_unit[material.index])
            tree.links.new(current, node.inputs["Image"])
            for name_in in ("diffuse", "diffuse_indirect", "albedo"):
                tree.links.new(_pass(source, PASS_INPUTS[name_in]), node.inputs[name_in])
            mask = _mask(tree, source, [material.index], technique, (x + 350 + 260 * k, y - 300))
            tree.links.new(mask, node.inputs["mask"])
            node.inputs["albedo_mode"].default_value = options.get("albedo_mode", "post")
            current = node.outputs["Image"]
        return current

    return add


_SCATTER_PASSES = ("Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Material Index")

#: Technique name -> how its node groups go into a compositor tree: the one list of the builders.
BUILDERS: dict[str, ChainBuilder] = {
    "sta": ChainBuilder(
        passes=("Diffuse Color", "Normal", "Position", "Material Index", THICKNESS),
        per_material=False,
        add=_add_sta,
        unmodelled=_sta_unmodelled,
    ),
    "ssss": ChainBuilder(passes=_SCATTER_PASSES, per_material=True, add=_scatter_adder("ssss", ensure_ssss_group)),
    "burley": ChainBuilder(
        passes=_SCATTER_PASSES, per_material=True, add=_scatter_adder("burley", ensure_burley_group)
    ),
}

#: Techniques without node groups, and why (the set-up says so instead of building anything).
NO_BUILDER: dict[str, str] = {
    "combined": "its light from behind needs every light's direction per pixel and the slab thickness, which the"
    " groups do not compute; use Apply instead",
}


def builder(technique: str) -> ChainBuilder:
    """The chain builder of ``technique``; ValueError saying why for a technique without one."""
    name = check_technique(technique)
    if name not in BUILDERS:
        reason = NO_BUILDER.get(name, "no node groups are written for it")
        raise ValueError(f"the {TECHNIQUES[name].label} technique has no compositor group: {reason}")
    return BUILDERS[name]


def remove_chain(tree) -> int:
    """Remove the nodes ``build_chain`` added to ``tree`` and reconnect what read the chain's
    result to the chain's input. Returns the number of nodes removed."""
    ours = _tagged(tree)
    if not ours:
        return 0
    names = {n.name for n in ours}
    source = None
    for node in ours:
        socket = node.inputs.get("Image")
        if socket is not None and socket.is_linked and socket.links[0].from_node.name not in names:
            source = socket.links[0].from_socket
            break
    readers = [link.to_socket for link in tree.links if link.from_node.name in names and link.to_node.name not in names]
    for node in ours:
        tree.nodes.remove(node)
    if source is not None:
        for socket in readers:
            tree.links.new(source, socket)
    return len(ours)


def _render_layers(tree, scene, layer):
    for node in tree.nodes:
        if node.bl_idname == "CompositorNodeRLayers" and node.layer == layer.name:
            if node.scene in (None, scene):
                return node
    node = tree.nodes.new("CompositorNodeRLayers")
    node.scene = scene
    node.layer = layer.name
    node.location = (-300.0, 0.0)
    return node


def insert_chain(
    scene,
    layer,
    *,
    technique: str,
    desc: SceneDescription,
    options: Mapping | None = None,
    pixels_per_unit: Mapping[int, float] | None = None,
) -> dict:
    """Insert ``technique``'s chain (``build_chain``) into ``scene``'s compositor tree (made if it
    has none) after the Image output of ``layer``'s Render Layers node (reused, or added): what read
    that output now reads the chain's result (with a new tree, the tree's output). A chain added
    earlier is removed first (``remove_chain``). Returns {"tree": its name, "groups", "nodes": the
    names of the nodes added, "removed": how many were, "notes": ``build_chain``'s}."""
    tree = compat.compositor_tree(scene, create=True)
    result = compat.compositor_result_socket(tree)
    removed = remove_chain(tree)
    rl = _render_layers(tree, scene, layer)
    image = rl.outputs["Image"]
    readers = [link.to_socket for link in tree.links if link.from_socket == image]
    if not readers and not result.is_linked:
        readers = [result]
    for link in [lk for lk in tree.links if lk.from_socket == image]:
        tree.links.remove(link)
    location = (rl.location[0] + 300.0, rl.location[1])
    output, notes = build_chain(
        tree,
        rl,
        image=image,
        technique=technique,
        scene=desc,
        options=options,
        pixels_per_unit=pixels_per_unit,
        location=location,
    )
    for socket in readers:
        tree.links.new(output, socket)
    added = [n.name for n in tree.nodes if NODE_TAG in n.keys()]
    groups = sorted({n.node_tree.name for n in tree.nodes if n.name in added and getattr(n, "node_tree", None)})
    return {"tree": tree.name, "groups": groups, "nodes": added, "removed": removed, "notes": notes}


def uses_node_groups(scene) -> bool:
    """True when a render of ``scene`` runs SSS Lab's compositor node groups: Cycles, compositing
    on, and a node ``build_chain`` added (not muted) in the scene's compositor tree."""
    if scene is None or scene.render.engine != "CYCLES" or not scene.render.use_compositing:
        return False
    tree = compat.compositor_tree(scene)
    return tree is not None and any(NODE_TAG in node.keys() and not node.mute for node in tree.nodes)
