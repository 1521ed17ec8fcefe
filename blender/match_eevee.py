"""Match EEVEE to Cycles' random walk, per material, in an EEVEE-only branch of the material.

``match_eevee(scene)`` (``match_eevee_job`` step by step) renders what it needs of the scene as
its user has it — Cycles' random walk and Cycles without scattering (the passes) at a few samples,
EEVEE with and without scattering — and gives each subsurface material an **EEVEE-only branch**:
a Material Output targeting EEVEE beside the one Cycles uses, fed by a copy of the shader nodes
from the Principled BSDF (or Subsurface Scattering node) to the output (Mix and Add Shaders,
reroutes, node groups copied as "<group> (EEVEE)"), the BSDF's inputs shared with the original
except the two the match sets (``core/study/eevee_match.py``):

- **Radius**, per channel, so that EEVEE gathers over k times its own d as authored
  (docs/references.md §18);
- **Base Color** times a gain g per channel (Cycles' walk shifts a material's energy where EEVEE's
  gather only moves it), the Radius set for the new colour so that d stays k times the authored;
- and, where it brings EEVEE closer, the Base Color also times the entry's dependence on the view
  angle (``set_view_factor``: a Color Ramp of the view cosine, ``eevee_match.view_table``): Cycles'
  walk returns less light seen straight on than at a grazing angle (docs/references.md §15), which
  a screen-space gather cannot do by itself;
- **Thickness** on the EEVEE output: where the material reads a thickness map SSS Lab baked, the
  slab thickness it stands for as the object-space length EEVEE expects (``wire_thickness``),
  in place of EEVEE's guess from the object's smallest dimension.

k is tried on ``eevee_match.K_GRID`` (one EEVEE frame each, every material at once) and then half
an octave either side of each material's best, g solved in closed form per k
(``eevee_match.solve_gain``), the best k kept per material. The result also gives k against SSS
Lab's own d for the material (``core.pipeline.mapping``), which reads the inputs 4π wider. A last frame checks
the match: a material whose EEVEE effect does not come closer to Cycles' than as authored gets no
branch (and the result says so). A linked Radius or Base Color gets a Vector Math node multiplying
it inside the branch. Cycles never reads the branch (it renders its own output, unchanged: the
tests compare its pixels); every node the match adds carries the custom property ``EEVEE_TAG``,
so ``remove_match`` takes it out in one step and a second match replaces the first. What was
matched is stored on the material (``MATCH_KEY``, JSON).
"""

from __future__ import annotations

import contextlib
import json
from dataclasses import dataclass, field

import bpy
import numpy as np

from ..core.base import arrays, files
from ..core.base.errors import InputError
from ..core.optics.energy import entry_view_cosine
from ..core.pipeline import plan, sequence
from ..core.pipeline.mapping import burley_d
from ..core.scene import exr
from ..core.scene.inputs import read_scene
from ..core.study import eevee_match
from . import shader_graph
from .describe import sss_materials
from .eevee import cached_eevee
from .jobs import Job, Steps, run
from .reference_cache import cached_reference, scene_fingerprint

#: Custom property on every node and node group the match adds.
EEVEE_TAG = "sss_lab_eevee"
#: Custom property on the material: what was matched (JSON).
MATCH_KEY = "sss_lab_eevee_match"
_COLOR_INPUTS = ("Base Color", "Color")
_RADIUS_INPUTS = ("Subsurface Radius", "Radius")
_SCALE_INPUTS = ("Subsurface Scale", "Scale")


@dataclass
class MatchSettings:
    """What ``match_eevee`` renders. Resolution None keeps the scene's."""

    resolution: tuple[int, int] | None = None
    #: Cycles random walk's samples (the SSS effect to match: its noise averages over the blocks).
    cycles_samples: int = 64
    #: Cycles without scattering (the passes).
    pass_samples: int = 16
    #: EEVEE's render samples; None keeps the scene's own.
    eevee_samples: int | None = None
    seed: int = 0
    #: Where the renders are cached (None: a temporary folder, removed at the end).
    cache_dir: str | None = None

    def validate(self) -> None:
        for name in ("cycles_samples", "pass_samples"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise InputError(f"{name}: expected an integer >= 1, got {v!r}")
        e = self.eevee_samples
        if e is not None and (isinstance(e, bool) or not isinstance(e, int) or e < 1):
            raise InputError(f"eevee_samples: expected an integer >= 1 (or None: the scene's own), got {e!r}")
        if self.resolution is not None:
            w, h = self.resolution
            if not (isinstance(w, int) and isinstance(h, int) and w >= eevee_match.BOX and h >= eevee_match.BOX):
                raise InputError(
                    f"resolution: expected two integers >= {eevee_match.BOX} (W, H), got {self.resolution!r}"
                )


@dataclass
class MaterialMatch:
    """One material's match: the scale of SSS Lab's d and the Base Color gain kept, the share of
    Cycles' SSS effect EEVEE reproduces as authored and with the branch (None: no effect to
    measure), and why it has no branch (None when it has one)."""

    name: str
    k: float | None = None
    gain: tuple[float, float, float] | None = None
    d: tuple[float, float, float] | None = None
    #: The d kept over SSS Lab's own d for the material (EEVEE as authored: 1 / (4π)).
    d_over_ssslab: float | None = None
    removed_before: float | None = None
    removed_after: float | None = None
    errors: dict = field(default_factory=dict)
    skipped: str | None = None
    #: True when the branch also multiplies the Base Color by the entry's view dependence
    #: (``set_view_factor``), because that brought EEVEE closer on the match's frame.
    view: bool = False
    #: What feeds the branch's Thickness (``wire_thickness``), None: EEVEE's own guess.
    thickness: str | None = None

    def to_dict(self) -> dict:
        return {
            "k": self.k,
            "gain": self.gain,
            "d": self.d,
            "d_over_ssslab": self.d_over_ssslab,
            "removed_before": self.removed_before,
            "removed_after": self.removed_after,
            "errors_by_k": self.errors,
            "skipped": self.skipped,
            "view": self.view,
            "thickness": self.thickness,
        }


# --- the branch ---------------------------------------------------------------------------------


def _tagged(idblock_or_node) -> bool:
    return bool(idblock_or_node.get(EEVEE_TAG))


def remove_match(material) -> bool:
    """Remove the match's branch from ``material`` (its nodes, its copied groups when nothing else
    uses them, the stored values); True when there was one."""
    tree = getattr(material, "node_tree", None)
    had = MATCH_KEY in material.keys()
    if tree is not None:
        groups = [n.node_tree for n in tree.nodes if _tagged(n) and n.bl_idname == "ShaderNodeGroup" and n.node_tree]
        for node in [n for n in tree.nodes if _tagged(n)]:
            tree.nodes.remove(node)
            had = True
        _remove_groups(groups)
    if MATCH_KEY in material.keys():
        del material[MATCH_KEY]
    return had


def _remove_groups(groups) -> None:
    for group in groups:
        if group is None or not _tagged(group) or group.users:
            continue
        inner = [n.node_tree for n in group.nodes if n.bl_idname == "ShaderNodeGroup" and n.node_tree]
        bpy.data.node_groups.remove(group)
        _remove_groups(inner)


def _user_eevee_output(tree):
    """An output targeting EEVEE that the match did not make (the user's own), or None."""
    return next(
        (n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial" and n.target == "EEVEE" and not _tagged(n)),
        None,
    )


def _contains_scattering(tree, seen=None) -> bool:
    seen = set() if seen is None else seen
    if tree is None or tree.name in seen:
        return False
    seen.add(tree.name)
    for n in tree.nodes:
        if n.bl_idname in shader_graph.SCATTERING:
            return True
        if n.bl_idname == "ShaderNodeGroup" and _contains_scattering(n.node_tree, seen):
            return True
    return False


def _reaches(node, memo: dict) -> bool:
    """True when a scattering node's closure can reach ``node``'s output (the nodes the branch copies)."""
    key = node.as_pointer()
    if key in memo:
        return memo[key]
    memo[key] = False  # a cycle (impossible in Blender) reads as no
    kind = node.bl_idname
    if node.mute:
        found = False
    elif kind in shader_graph.SCATTERING:
        found = True
    elif kind == "ShaderNodeGroup":
        found = _contains_scattering(node.node_tree) or any(_input_reaches(s, memo) for s in node.inputs)
    elif kind in ("ShaderNodeMixShader", "ShaderNodeAddShader", "NodeReroute"):
        found = any(_input_reaches(s, memo) for s in node.inputs)
    else:
        found = False
    memo[key] = found
    return found


def _input_reaches(socket, memo) -> bool:
    return any(link.is_valid and _reaches(link.from_node, memo) for link in socket.links)


_SKIP_PROPS = {"rna_type", "name", "label", "location", "width", "height", "parent", "select", "node_tree", "type"}


def _copy_node(tree, node):
    new = tree.nodes.new(node.bl_idname)
    for prop in node.bl_rna.properties:
        ident = prop.identifier
        if prop.is_readonly or ident in _SKIP_PROPS or prop.type in {"POINTER", "COLLECTION"}:
            continue
        try:
            setattr(new, ident, getattr(node, ident))
        except (AttributeError, TypeError, ValueError):
            pass
    new.label = node.label
    new.location = (node.location.x, node.location.y - 600.0)
    new[EEVEE_TAG] = True
    return new


def _copied_group(group, made: dict):
    if group.name in made:
        return made[group.name]
    copy = group.copy()
    copy.name = f"{group.name} (EEVEE)"
    copy[EEVEE_TAG] = True
    made[group.name] = copy
    for n in copy.nodes:
        if n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None and _contains_scattering(n.node_tree):
            n.node_tree = _copied_group(n.node_tree, made)
    return copy


def _clone(tree, socket, made: dict, groups: dict, memo: dict):
    """The socket of the branch's copy of ``socket``'s node (the original socket for a node no
    scattering reaches: shared with Cycles' graph)."""
    node = socket.node
    if not _reaches(node, memo):
        return socket
    key = node.as_pointer()
    if key not in made:
        new = _copy_node(tree, node)
        if node.bl_idname == "ShaderNodeGroup":
            new.node_tree = _copied_group(node.node_tree, groups)
        made[key] = new
        for i, inp in enumerate(node.inputs):
            links = [link for link in inp.links if link.is_valid and not getattr(link, "is_muted", False)]
            if links:
                tree.links.new(_clone(tree, links[0].from_socket, made, groups, memo), new.inputs[i])
            elif hasattr(inp, "default_value") and i < len(new.inputs) and hasattr(new.inputs[i], "default_value"):
                try:
                    new.inputs[i].default_value = inp.default_value
                except (TypeError, ValueError):
                    pass
    new = made[key]
    index = list(node.outputs).index(socket)
    return new.outputs[index]


def add_branch(material) -> list:
    """Give ``material`` an EEVEE-only output fed by a copy of its scattering shader (module
    docstring); returns the copied scattering nodes (``shader_graph.Source`` each). Raises
    InputError when the material cannot get one (no node tree, no output Cycles renders, an
    EEVEE output of the user's own)."""
    tree = getattr(material, "node_tree", None)
    name = material.name
    if tree is None:
        raise InputError(f"material {name!r} uses no nodes: nothing to copy for EEVEE")
    own = _user_eevee_output(tree)
    if own is not None:
        raise InputError(
            f"material {name!r} already has an output for EEVEE ({own.name!r}): match-eevee would hide it;"
            " remove it (or set its target to All) first"
        )
    output = shader_graph.output_node(tree)
    if output is None or not output.inputs["Surface"].is_linked:
        raise InputError(f"material {name!r} has no active Material Output with a Surface Cycles renders")
    made: dict = {}
    groups: dict = {}
    memo: dict = {}
    new_output = tree.nodes.new("ShaderNodeOutputMaterial")
    new_output.target = "EEVEE"
    new_output.name = new_output.label = "EEVEE (SSS Lab match)"
    new_output.location = (output.location.x, output.location.y - 600.0)
    new_output[EEVEE_TAG] = True
    for socket_name in ("Surface", "Volume", "Displacement", "Thickness"):
        target = output.inputs.get(socket_name)
        if target is None or socket_name not in new_output.inputs:
            continue
        links = [link for link in target.links if link.is_valid]
        if links:
            src = links[0].from_socket
            if socket_name == "Surface":
                src = _clone(tree, src, made, groups, memo)
            tree.links.new(src, new_output.inputs[socket_name])
    found: list = []
    shader_graph.follow(new_output.inputs["Surface"], found)
    return found


def _scaled_input(node, name: str, factor) -> None:
    """Set ``node``'s input ``name`` to its authored value times ``factor`` (R, G, B): through a
    tagged Vector Math node when linked (made once, its factor replaced afterwards)."""
    socket = node.inputs[name]
    tree = node.id_data
    links = [link for link in socket.links if link.is_valid]
    factor = tuple(float(v) for v in factor)
    if links:
        src = links[0].from_node
        if _tagged(src) and src.bl_idname == "ShaderNodeVectorMath" and src.get("sss_lab_scales") == name:
            src.inputs[1].default_value = factor
            return
        mult = tree.nodes.new("ShaderNodeVectorMath")
        mult.operation = "MULTIPLY"
        mult[EEVEE_TAG] = True
        mult["sss_lab_scales"] = name
        mult.label = f"{name} for EEVEE (SSS Lab match)"
        mult.location = (node.location.x - 220.0, node.location.y)
        tree.links.new(links[0].from_socket, mult.inputs[0])
        mult.inputs[1].default_value = factor
        tree.links.new(mult.outputs[0], socket)
        return
    authored = node.get(f"sss_lab_authored_{name}")
    if authored is None:
        authored = list(socket.default_value)[:3]
        node[f"sss_lab_authored_{name}"] = authored
    value = list(socket.default_value)
    value[:3] = [a * f for a, f in zip(authored, factor, strict=True)]
    socket.default_value = value


def _input_name(node, names) -> str:
    return next(n for n in names if n in node.inputs)


def set_branch(source, d_now, color_now, d_wanted, gain) -> None:
    """Set a copied scattering node so that EEVEE gathers over ``d_wanted`` with its Base Color
    times ``gain``: ``d_now`` is EEVEE's d of the authored inputs at the authored colour
    ``color_now`` (medians where linked)."""
    node = source.node
    scale = float(node.inputs[_input_name(node, _SCALE_INPUTS)].default_value)
    gain = np.asarray(gain, np.float64)
    new_color = np.clip(np.asarray(color_now, np.float64) * gain, 0.0, 1.0)
    _scaled_input(node, _input_name(node, _COLOR_INPUTS), gain)
    # The Radius that gives d_wanted at the new colour, as a factor on the authored Radius.
    radius_now = eevee_match.eevee_radius(d_now, scale if scale > 0 else 1.0, color_now)
    radius_wanted = eevee_match.eevee_radius(d_wanted, scale if scale > 0 else 1.0, new_color)
    factor = np.where(radius_now > 0, radius_wanted / np.where(radius_now > 0, radius_now, 1.0), 1.0)
    _scaled_input(node, _input_name(node, _RADIUS_INPUTS), factor)


def _new(tree, kind: str, label: str, location):
    node = tree.nodes.new(kind)
    node[EEVEE_TAG] = True
    node.label = label
    node.location = location
    return node


def set_view_factor(source, table) -> None:
    """Multiply the copied scattering node's Base Color by a Color Ramp of the view cosine
    (``eevee_match.view_table``: Geometry's Normal dot Incoming, its absolute value, the ramp's
    stops): the entry's view dependence that Cycles' walk shows and EEVEE's gather does not. The
    nodes are tagged, so ``remove_match`` removes them with the branch."""
    node = source.node
    tree = node.id_data
    socket = node.inputs[_input_name(node, _COLOR_INPUTS)]
    x, y = node.location.x - 900.0, node.location.y - 300.0
    geometry = _new(tree, "ShaderNodeNewGeometry", "View for EEVEE (SSS Lab match)", (x, y))
    dot = _new(tree, "ShaderNodeVectorMath", "View cosine", (x + 180.0, y))
    dot.operation = "DOT_PRODUCT"
    absolute = _new(tree, "ShaderNodeMath", "|View cosine|", (x + 360.0, y))
    absolute.operation = "ABSOLUTE"
    ramp = _new(tree, "ShaderNodeValToRGB", "Entry gain by view angle (SSS Lab match)", (x + 540.0, y))
    multiply = _new(tree, "ShaderNodeVectorMath", "Base Color x entry gain", (x + 820.0, y + 150.0))
    multiply.operation = "MULTIPLY"
    tree.links.new(geometry.outputs["Normal"], dot.inputs[0])
    tree.links.new(geometry.outputs["Incoming"], dot.inputs[1])
    tree.links.new(dot.outputs["Value"], absolute.inputs[0])
    tree.links.new(absolute.outputs[0], ramp.inputs["Fac"])
    mu, factors = table
    elements = ramp.color_ramp.elements
    ramp.color_ramp.interpolation = "LINEAR"
    # The two default stops become the ends, the others are made in place (a stop keeps the ramp
    # sorted by position: setting positions one by one would move stops under the loop).
    elements[0].position, elements[-1].position = float(mu[0]), float(mu[-1])
    for position in mu[1:-1]:
        elements.new(float(position))
    for element, factor in zip(elements, factors, strict=True):
        element.color = (*(float(v) for v in factor), 1.0)
    links = [link for link in socket.links if link.is_valid]
    if links:
        tree.links.new(links[0].from_socket, multiply.inputs[0])
    else:
        multiply.inputs[0].default_value = tuple(socket.default_value)[:3]
    tree.links.new(ramp.outputs["Color"], multiply.inputs[1])
    tree.links.new(multiply.outputs[0], socket)


def wire_thickness(scene, material) -> str | None:
    """Feed the EEVEE output of ``material``'s branch the slab thickness its baked map stands for,
    as the object-space length EEVEE's Thickness socket reads (docs/references.md §19): the map
    the material's thickness AOV reads (``blender.thickness.thickness_source``), through tagged Math
    nodes, D sqrt(inside AO) / s (``core.scene.thickness.object_thickness_su``; D the bake distance,
    s the smallest scale of the first object that carries the material, since EEVEE multiplies
    the socket by the object's scale and takes the smallest axis). Returns what was wired, in
    words, or None when the material has no map SSS Lab baked (EEVEE then guesses from the
    object's smallest dimension, as authored)."""
    from .describe import bake_distance
    from .thickness import source_convention, thickness_aov_name, thickness_source

    tree = material.node_tree
    output = next(
        (n for n in tree.nodes if _tagged(n) and n.bl_idname == "ShaderNodeOutputMaterial" and n.target == "EEVEE"),
        None,
    )
    source = thickness_source(material, thickness_aov_name(scene))
    distance = bake_distance(scene, material)
    if output is None or source is None or not distance > 0:
        return None
    aov = next(
        n
        for n in tree.nodes
        if n.bl_idname == "ShaderNodeOutputAOV" and any(link.from_node == source for i in n.inputs for link in i.links)
    )
    from_socket = next(link.from_socket for i in aov.inputs for link in i.links if link.from_node == source)
    convention = source_convention(scene, material, source) or "translucency"
    holders = [o for o in scene.objects if any(slot.material == material for slot in o.material_slots)]
    scales = [min(abs(v) for v in o.matrix_world.to_scale()) for o in holders]
    scale = scales[0] if scales and scales[0] > 0 else 1.0
    x, y = output.location.x - 720.0, output.location.y - 200.0
    value = from_socket
    if convention == "translucency":  # inside AO = 1 - the map
        flip = _new(tree, "ShaderNodeMath", "Inside AO", (x, y))
        flip.operation = "SUBTRACT"
        flip.inputs[0].default_value = 1.0
        tree.links.new(value, flip.inputs[1])
        value = flip.outputs[0]
    root = _new(tree, "ShaderNodeMath", "Thickness over D", (x + 180.0, y))
    root.operation = "SQRT"
    tree.links.new(value, root.inputs[0])
    length = _new(tree, "ShaderNodeMath", "Object-space thickness (SSS Lab)", (x + 360.0, y))
    length.operation = "MULTIPLY"
    tree.links.new(root.outputs[0], length.inputs[0])
    length.inputs[1].default_value = distance / scale
    tree.links.new(length.outputs[0], output.inputs["Thickness"])
    what = f"{source.bl_idname.removeprefix('ShaderNode')} {convention} map, D {distance:.4g}"
    if len({round(s, 6) for s in scales}) > 1:
        what += f" (the scale of {holders[0].name!r}; the material's objects differ in scale)"
    return what


# --- the match ----------------------------------------------------------------------------------


def match_eevee(scene, settings: MatchSettings | None = None, *, log=print) -> dict:
    """Match every subsurface material of ``scene`` (``match_eevee_job`` to its end)."""
    return run(match_eevee_job(scene, settings, log=log))


def match_eevee_job(scene, settings: MatchSettings | None = None, *, log=print) -> Job:
    """The match as a job (one step per render). The scene keeps its render settings; its
    subsurface materials get their branches (a previous match is replaced). Stopped or failed
    before the end, every branch it added is taken out again."""
    settings = settings or MatchSettings()
    settings.validate()
    say = log or (lambda _line: None)
    if scene.camera is None:
        raise InputError(f"scene {scene.name!r} has no active camera; set one in Scene Properties > Camera")
    materials = sss_materials(scene)
    if not materials:
        raise InputError(f"scene {scene.name!r} has no material with subsurface scattering: nothing to match")
    blender_mats = {m.name: bpy.data.materials[m.name] for m in materials if m.name in bpy.data.materials}
    steps = Steps(5 + len(eevee_match.K_GRID) + 2 + 1)
    tmp = contextlib.ExitStack()
    cache = settings.cache_dir
    if cache is None:
        cache = tmp.enter_context(files.temporary_folder("sss_lab_match_"))
    done = False
    try:
        for mat in blender_mats.values():
            remove_match(mat)  # from the scene as authored: a second match replaces the first
        yield steps.next(f"Cycles random walk, {settings.cycles_samples} samples")
        fingerprint = scene_fingerprint(scene)
        c_sss, _, _ = cached_reference(
            scene,
            cache,
            samples=settings.cycles_samples,
            seed=settings.seed,
            resolution=settings.resolution,
            method=None,
            log=say,
            fingerprint=fingerprint,
        )
        yield steps.next(f"Cycles without scattering (passes), {settings.pass_samples} samples")
        passes, desc = _passes(scene, settings, say)
        c_none = passes["Combined"]
        index = plan.index_map(passes)
        read = {m.name: m for m in read_scene(passes, desc).materials if m.scatters}

        def eevee(sss: bool):
            return cached_eevee(
                scene,
                cache,
                samples=settings.eevee_samples,
                resolution=settings.resolution,
                sss=sss,
                fingerprint=scene_fingerprint(scene),
                log=say,
                warm_up=False,  # the match does not use the seconds
            )[0]

        yield steps.next("EEVEE as authored, scattering on")
        e_authored = eevee(True)
        yield steps.next("EEVEE, scattering off")
        e_none = eevee(False)
        target = eevee_match.target_image(e_none, c_sss, c_none)
        results: dict[str, MaterialMatch] = {}
        branches: dict[str, list] = {}
        keeps: dict[str, np.ndarray] = {}
        for name, mat in blender_mats.items():
            result = results[name] = MaterialMatch(name)
            m = read.get(name)
            if m is None:
                result.skipped = "not on screen"
                continue
            keep = eevee_match.material_blocks(index == m.index)
            if not keep.any():
                result.skipped = "too small on screen (no 2 x 2 block inside it)"
                continue
            keeps[name] = keep
            result.removed_before = eevee_match.effect_removed(e_authored, e_none, c_sss, c_none, keep)
            try:
                branches[name] = add_branch(mat)
            except InputError as exc:
                result.skipped = str(exc)
                continue
            if not branches[name]:
                remove_match(mat)
                del branches[name]
                result.skipped = "no scattering node reaches its EEVEE output"
                continue
            result.thickness = wire_thickness(scene, mat)
        d_ssslab = {name: np.asarray(burley_d(read[name]), np.float64) for name in branches}
        colors = {name: np.clip(np.asarray(read[name].base_color, np.float64), 0.0, 1.0) for name in branches}
        d_eevee = {
            name: eevee_match.eevee_d(read[name].radius, 1.0, colors[name]) for name in branches
        }  # the radius read is Radius x Scale already (MaterialSSS.radius)
        views = {
            name: _view_factor(passes, desc, index == read[name].index, read[name], colors[name]) for name in branches
        }

        def set_all(k_of, gain_of) -> None:
            for name, sources in branches.items():
                for source in sources:
                    set_branch(source, d_eevee[name], colors[name], k_of(name) * d_eevee[name], gain_of(name))

        yield steps.next("EEVEE with the Base Color black (what the albedo does not scale)")
        set_all(lambda _n: 1.0, lambda _n: (0.0, 0.0, 0.0))
        e_rest = eevee(True)
        # (k, with the view factor) -> (gain, error) per material.
        trials: dict[str, dict[tuple[float, bool], tuple]] = {name: {} for name in branches}

        def solve(name: str, e_k, k: float, label: str) -> None:
            """Material ``name``'s gains for EEVEE's frame ``e_k`` at width ``k``, with and (where the
            method has one) without the view ramp."""
            trials[name][(k, False)] = eevee_match.solve_gain(e_k, e_rest, target, keeps[name])
            results[name].errors[label] = trials[name][(k, False)][1]
            if views[name] is not None:
                one = e_rest[..., :3] + views[name] * (e_k[..., :3] - e_rest[..., :3])
                trials[name][(k, True)] = eevee_match.solve_gain(one, e_rest, target, keeps[name])
                results[name].errors[f"{label} view"] = trials[name][(k, True)][1]

        for k in eevee_match.K_GRID:
            yield steps.next(f"EEVEE with d x {k:g}")
            set_all(lambda _n, k=k: k, lambda _n: (1.0, 1.0, 1.0))
            e_k = eevee(True)
            for name in branches:
                solve(name, e_k, k, f"{k:g}")
        best = {name: _lowest(trials[name]) for name in branches}
        # Half an octave either side of each material's best (every material at once: the i-th side).
        for side in (2**-0.5, 2**0.5):
            yield steps.next(f"EEVEE with each material's best d x {side:.3g}")
            set_all(lambda n, side=side: best[n][0] * side, lambda _n: (1.0, 1.0, 1.0))
            e_k = eevee(True)
            for name in branches:
                k = best[name][0] * side
                solve(name, e_k, k, f"{k:.4g}")
        best = {name: _lowest(trials[name]) for name in branches}
        yield steps.next("EEVEE with the match, to check it")
        set_all(lambda n: best[n][0], lambda n: tuple(trials[n][best[n]][0]))
        for name, sources in branches.items():
            if best[name][1]:
                for source in sources:
                    set_view_factor(source, eevee_match.view_table(read[name].method, colors[name]))
        e_after = eevee(True)
        for name in list(branches):
            r = results[name]
            k_best, r.view = float(best[name][0]), bool(best[name][1])
            r.k = k_best
            gr, gg, gb = (float(v) for v in trials[name][best[name]][0])
            r.gain = (gr, gg, gb)
            dr, dg, db = (float(v) for v in k_best * d_eevee[name])
            r.d = (dr, dg, db)
            r.d_over_ssslab = float(k_best * np.mean(d_eevee[name] / np.where(d_ssslab[name] > 0, d_ssslab[name], 1.0)))
            r.removed_after = eevee_match.effect_removed(e_after, e_none, c_sss, c_none, keeps[name])
            if r.removed_after is None or (r.removed_before is not None and r.removed_after <= r.removed_before):
                remove_match(blender_mats[name])
                r.skipped = (
                    f"the match reproduces {_pct(r.removed_after)} of Cycles' SSS effect, as authored"
                    f" {_pct(r.removed_before)}: left as authored"
                )
                del branches[name]
                continue
            blender_mats[name][MATCH_KEY] = json.dumps(
                dict(r.to_dict(), cycles_samples=settings.cycles_samples, eevee_samples=settings.eevee_samples)
            )
        for r in results.values():
            say(_line(r))
        done = True
        return {
            "materials": {name: r.to_dict() for name, r in results.items()},
            "settings": {
                "cycles_samples": settings.cycles_samples,
                "pass_samples": settings.pass_samples,
                "eevee_samples": settings.eevee_samples or scene.eevee.taa_render_samples,
                "resolution": list(c_sss.shape[1::-1]),
            },
        }
    finally:
        if not done:
            for mat in blender_mats.values():
                remove_match(mat)
        tmp.close()


def _lowest(trials: dict):
    """The trial (k, view) whose (gain, error) has the lowest error."""
    return min(trials, key=lambda k: trials[k][1])


def _pct(v) -> str:
    return "n/a" if v is None else f"{100 * v:.0f} %"


def _line(r: MaterialMatch) -> str:
    if r.skipped:
        return f"  {r.name}: no EEVEE branch ({r.skipped})"
    gain = ", ".join(f"{v:.3g}" for v in r.gain or ())
    return (
        f"  {r.name}: EEVEE's d x {r.k:.3g} (SSS Lab's x {r.d_over_ssslab:.3g}), Base Color x ({gain})"
        + (" and the view angle's ramp" if r.view else "")
        + (f", Thickness from the {r.thickness}" if r.thickness else "")
        + ": reproduces"
        f" {_pct(r.removed_after)} of Cycles' SSS effect (as authored {_pct(r.removed_before)})"
    )


def _view_factor(passes, desc, mask: np.ndarray, material, color) -> np.ndarray | None:
    """The entry's view dependence per pixel on ``mask`` (``eevee_match.view_factor``, 1 elsewhere)
    for ``material``'s method at ``color``, the view cosine from the passes' Normal (else Depth);
    None for a method without one."""
    table = eevee_match.view_table(material.method, color)
    box = arrays.bounding_box(mask)
    if table is None or box is None:
        return None
    normal = passes["Normal"] if "Normal" in passes else None
    cos = np.ones(mask.shape, np.float64)
    cos[box] = entry_view_cosine(passes["Depth"], normal, mask, desc.camera, box)
    factor = eevee_match.view_factor(cos, table)
    factor[~mask] = 1.0
    return factor


def _passes(scene, settings: MatchSettings, say):
    """Cycles without scattering at the pass samples (``render_passes``): (passes, description),
    rendered into a temporary folder that is removed once they are read (they are not cached: a
    cache folder the user keeps would gather a copy per match)."""
    from .render_passes import render_passes

    with files.temporary_folder("sss_lab_match_passes_") as folder:
        written = render_passes(
            scene,
            folder,
            techniques=("burley",),
            samples=settings.pass_samples,
            resolution=settings.resolution,
            seed=settings.seed,
            overwrite=True,
            log=None,  # a temporary file: its Saved lines would name what is removed at the end
        )
        path = next(p for p in written if p.endswith(".exr"))
        return exr.read_passes(path), sequence.load_scene(path)
