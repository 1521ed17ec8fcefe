"""Where a material's Principled BSDF (or Subsurface Scattering node) is, and what its inputs
hold, as Cycles follows the nodes.

Cycles renders the closure that reaches the material output's Surface through Mix and Add
Shaders, reroutes and node groups (nested, each group's output leading to its Group Output and a
Group Input back to the group node's socket). ``principled_sources`` follows the same links and
returns each Principled BSDF or Subsurface Scattering node found with the group nodes it sits in
and its share of the surface (the Mix Shaders' factors along the way; unknown where a factor is
linked).

``input_value`` reads an input as Cycles would see it where that is a constant: its own value,
or a Value or RGB node's, through reroutes and group sockets. Anything else (a texture, an
attribute, a Math node) cannot be read without evaluating the shader: it says what the input is
linked to, and the caller says which value it uses instead. Reads only.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

PRINCIPLED = "ShaderNodeBsdfPrincipled"
SUBSURFACE = "ShaderNodeSubsurfaceScattering"
#: The nodes whose closure scatters below the surface.
SCATTERING = (PRINCIPLED, SUBSURFACE)
_MIX, _ADD, _REROUTE, _GROUP = "ShaderNodeMixShader", "ShaderNodeAddShader", "NodeReroute", "ShaderNodeGroup"
_GROUP_INPUT, _GROUP_OUTPUT = "NodeGroupInput", "NodeGroupOutput"
_CONSTANTS = {"ShaderNodeValue", "ShaderNodeRGB"}
#: How deep groups may nest before the search stops (a group cannot contain itself in Blender;
#: this only bounds a damaged file).
MAX_DEPTH = 32


@dataclass
class Source:
    """A Principled BSDF or Subsurface Scattering node reaching the output: the node, the group
    nodes around it (outermost first), its share of the surface (None: a linked Mix factor
    decides it per pixel) and how it was reached (for messages)."""

    node: Any
    groups: tuple = ()
    share: float | None = 1.0
    path: list[str] = field(default_factory=list)


def _label(node) -> str:
    return f"{node.bl_rna.name} {node.name!r}"


def _output_node(tree, kinds=("CYCLES", "ALL")):
    for target in kinds:
        node = tree.get_output_node(target)
        if node is not None:
            return node
    return None


def output_node(tree):
    """The Material Output Cycles renders from (targeting Cycles, or All), or None."""
    return _output_node(tree)


def follow(socket, found: list) -> None:
    """Append to ``found`` every scattering node whose closure reaches ``socket`` (a Surface input
    of any output), as ``principled_sources`` follows them."""
    _follow(socket, (), 1.0, [], found)


def _group_output(tree):
    outputs = [n for n in tree.nodes if n.bl_idname == _GROUP_OUTPUT]
    return next((n for n in outputs if getattr(n, "is_active_output", False)), outputs[0] if outputs else None)


def _linked_from(socket):
    """The (node, output socket) ``socket`` is linked from, skipping muted links, or None."""
    for link in socket.links:
        if not getattr(link, "is_muted", False) and link.is_valid:
            return link.from_node, link.from_socket
    return None


def renders_an_output(material) -> bool:
    """True when ``material``'s tree has an active output Cycles renders (then what reaches its
    Surface, and nothing else, is what Cycles renders)."""
    tree = getattr(material, "node_tree", None)
    return tree is not None and _output_node(tree) is not None


def principled_sources(material) -> list[Source]:
    """The Principled BSDFs and Subsurface Scattering nodes whose closure reaches ``material``'s
    active Cycles output, in the order the links reach them; [] when none does (or the material
    uses no nodes)."""
    tree = getattr(material, "node_tree", None)
    output = _output_node(tree) if tree is not None else None
    if output is None or "Surface" not in output.inputs:
        return []
    found: list[Source] = []
    _follow(output.inputs["Surface"], (), 1.0, [], found)
    return found


def _follow(socket, groups: tuple, share, path: list[str], found: list[Source]) -> None:
    if len(groups) > MAX_DEPTH:
        return
    src = _linked_from(socket)
    if src is None:
        return
    node, out = src
    if node.mute:
        return
    kind = node.bl_idname
    if kind in SCATTERING:
        found.append(Source(node, groups, share, [*path, _label(node)]))
    elif kind == _MIX:
        fac = node.inputs[0]
        f = None if fac.is_linked or share is None else min(max(float(fac.default_value), 0.0), 1.0)
        here = [*path, _label(node)]
        _follow(node.inputs[1], groups, None if f is None else share * (1.0 - f), here, found)
        _follow(node.inputs[2], groups, None if f is None else share * f, here, found)
    elif kind == _ADD:
        here = [*path, _label(node)]
        _follow(node.inputs[0], groups, share, here, found)
        _follow(node.inputs[1], groups, share, here, found)
    else:
        step = _step(node, out, groups)
        if step is not None and step[0] is not None:
            _follow(step[0], step[1], share, [*path, _label(node)] if kind == _GROUP else path, found)


def _step(node, out, groups: tuple):
    """Where a reroute, a group node or a Group Input takes what its output ``out`` gives from:
    (that input socket, the group nodes around it), the socket None where the group has no
    matching one; None for any other node."""
    kind = node.bl_idname
    if kind == _REROUTE:
        return node.inputs[0], groups
    if kind == _GROUP and node.node_tree is not None:
        inner = _group_output(node.node_tree)
        return (inner.inputs.get(out.name) if inner is not None else None), (*groups, node)
    if kind == _GROUP_INPUT and groups:
        return groups[-1].inputs.get(out.name), groups[:-1]
    return None


def input_value(socket, groups: tuple = ()) -> tuple[Any, str]:
    """(the value ``socket`` holds, how it was read): its default value when nothing is linked
    to it, else a Value or RGB node's output followed through reroutes and group sockets
    (``groups``: the group nodes the socket's node sits in, outermost first). (None, what it is
    linked to) when the value depends on the shading point."""
    via = ""
    for _ in range(MAX_DEPTH + 1):
        src = _linked_from(socket)
        if src is None:
            return socket.default_value, f"typed in{via}"
        node, out = src
        where = _label(node)
        via = f" (through {where})"
        if node.mute:
            return None, f"linked to {where}, which is muted"
        kind = node.bl_idname
        if kind in _CONSTANTS:
            return out.default_value, f"linked to {where}"
        step = _step(node, out, groups)
        if step is None:
            return None, f"linked to {where}"
        if step[0] is None:
            if kind == _GROUP_INPUT:
                return None, f"linked to {where}'s {out.name!r}, which its group node lacks"
            return None, f"linked to {where}, whose group has no output {out.name!r}"
        socket, groups = step
    return None, f"linked through more than {MAX_DEPTH} groups"
