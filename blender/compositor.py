"""The scene side of the compositor set-up: what a technique's node groups need from the scene.

``operators/compositing.py``'s ``setup_compositor(scene, technique)`` is the plain function of the
set-up (``bpy.ops.sss_lab.setup_compositor`` wraps it for the panel); it calls ``prepare_scene``
here, then ``nodes.setup.insert_chain``, which wires the groups into the compositor tree. What the
set-up changes, on purpose and for good (it is a set-up, undoable with Ctrl+Z, not a temporary
change):

- the scene gets a compositor node group if it has none (5.x: ``scene.compositing_node_group``);
- a Render Layers node for the view layer is reused, or added; the technique's group nodes are
  inserted after its Image output: whatever read that output now reads the result (with a new
  tree, the tree's output). Nodes added by an earlier set-up are removed first (and only those:
  they carry the ``sss_lab`` custom property), so running it twice adds nothing twice;
- the view layer gets the passes the groups read (Diffuse Direct/Indirect/Color, Material
  Index; STA: Normal, Position and the thickness AOV), and each subsurface material gets the
  Pass Index the scene description gives it (1, 2, ... in name order), so that its mask is its
  Material Index, as with ``render_passes``.

Not changed: the materials' subsurface settings. Cycles puts its own subsurface light into the
Diffuse passes, so the groups need the materials rendered as plain diffuse: the render handlers
of ``addon/compositor_render.py`` do that around every render of the scene (Subsurface Weight 0
while it renders, put back after, as Render Passes does), and the set-up switches on Lock
Interface for them. Each subsurface material keeps the weight the set-up saw (custom property
``stored.KEPT_WEIGHT``), so that a set-up run again after the weight was set to 0 (by hand, as
the compositor path once required) still finds the material.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import bpy
import numpy as np

from ..core.scene.passes import THICKNESS, view_layer_flag
from ..core.scene.scene import SceneDescription
from .describe import describe_scene, principled_node, sss_materials, world_corners
from .stored import KEPT_WEIGHT
from .thickness import thickness_aov_name, thickness_setup


def material_depths(scene, camera) -> dict[str, float]:
    """Material name -> planar view depth of the objects using it (median of their bounding-box
    centres; only objects in front of the camera)."""
    forward = camera.forward
    origin = camera.position
    depths: dict[str, list[float]] = {}
    for obj in scene.objects:
        if obj.type != "MESH" or obj.hide_render:
            continue
        z = float((world_corners(obj).mean(axis=0) - origin) @ forward)
        if z <= 0:
            continue
        for slot in obj.material_slots:
            if slot.material is not None:
                depths.setdefault(slot.material.name, []).append(z)
    return {name: float(np.median(zs)) for name, zs in depths.items()}


def _enable_passes(layer, names, aov_name: str | None) -> list[str]:
    enabled = []
    for name in names:
        flag = view_layer_flag(name)
        if not getattr(layer, flag):
            setattr(layer, flag, True)
            enabled.append(name)
    if aov_name and layer.aovs.get(aov_name) is None:
        aov = layer.aovs.add()
        aov.name, aov.type = aov_name, "VALUE"
        enabled.append(f"AOV {aov_name}")
    return enabled


def _set_pass_indices(materials) -> tuple[list[str], list[str]]:
    """Pass Index = the description's index for each subsurface material; (changed, warnings)."""
    changed, warnings = [], []
    wanted = {m.name: m.index for m in materials}
    for mat in bpy.data.materials:
        if mat.name in wanted:
            if mat.pass_index != wanted[mat.name]:
                if not mat.is_editable:
                    warnings.append(f"{mat.name}: linked from a library, its Pass Index cannot be set")
                    continue
                mat.pass_index = wanted[mat.name]
                changed.append(f"{mat.name}={wanted[mat.name]}")
        elif mat.users and mat.pass_index in wanted.values():
            warnings.append(
                f"{mat.name} has Pass Index {mat.pass_index}, which is also a subsurface material's: "
                "its pixels get that material's SSS"
            )
    return changed, warnings


def _keep_weights(materials) -> list[str]:
    """Store each subsurface material's Subsurface Weight on it (``KEPT_WEIGHT``); notes for the
    materials that read 0 and were found by a weight kept earlier."""
    notes = []
    for m in materials:
        mat = bpy.data.materials.get(m.name)
        node = principled_node(mat)
        socket = node.inputs.get("Subsurface Weight") if node is not None else None
        if socket is None or not mat.is_editable:
            continue
        if socket.default_value > 0 or socket.is_linked:
            mat[KEPT_WEIGHT] = float(socket.default_value)
        else:
            notes.append(
                f"{m.name}: Subsurface Weight is 0; using {m.subsurface_weight:g}, the weight the last set-up saw "
                "(it need not be 0: SSS Lab renders the material as plain diffuse for the node groups)"
            )
    return notes


@dataclass
class PreparedScene:
    """What ``prepare_scene`` found and changed, for the tree's wiring and the set-up's report."""

    #: The view layer whose Render Layers node the groups read.
    layer: Any
    #: The scene description the groups are built from (its subsurface materials, camera, lights).
    desc: SceneDescription
    #: Material index -> the kernel's fixed screen scale (per-material builders only).
    pixels_per_unit: dict = field(default_factory=dict)
    #: Subsurface material names by index (for the report's ``pixels_per_unit``).
    materials: list = field(default_factory=list)
    passes_enabled: list = field(default_factory=list)
    pass_indices: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    warnings: list = field(default_factory=list)


def screen_scales(scene, desc: SceneDescription) -> dict[int, float]:
    """Material pass index -> pixels per scene unit at the material's depth (its objects' centres in
    front of the camera, ``material_depths``) for the camera of ``desc``."""
    scale = {}
    depths = material_depths(scene, desc.camera)
    for m in desc.materials:
        if m.name in depths:
            z = np.array([[depths[m.name]]], np.float32)
            scale[m.index] = float(desc.camera.pixels_per_unit(z)[0, 0])
    return scale


def prepare_scene(
    scene, *, passes: tuple[str, ...], per_material: bool, unmodelled: list[str], view_layer=None
) -> PreparedScene:
    """Ready ``scene`` for node groups that read ``passes`` (``nodes.setup.ChainBuilder.passes``):
    the checks, the thickness AOV's convention (STA), the passes, the pass indices, the kept
    weights, Lock Interface, and each material's screen scale when the builder has one group per
    material (``per_material``). ``unmodelled``: the builder's warnings for the options it does
    not model (they follow the thickness warnings in the report).

    Raises ValueError (not Cycles, no subsurface material, thickness maps that do not fit STA)
    before changing anything.
    """
    layer = view_layer or bpy.context.view_layer
    if layer is None or layer.name not in scene.view_layers:
        layer = scene.view_layers[0]
    if scene.render.engine != "CYCLES":
        raise ValueError(
            f"the compositor groups read Cycles passes (Material Index, Diffuse Direct/Indirect); scene "
            f"{scene.name!r} renders with {scene.render.engine}: set Render Engine to Cycles"
        )
    materials = sss_materials(scene, kept_weight=lambda mat: mat.get(KEPT_WEIGHT))
    if not materials:
        raise ValueError(
            f"scene {scene.name!r} has no material with subsurface scattering (Subsurface Weight, Radius and "
            "Scale > 0 on a Principled BSDF): nothing to set up (keep the materials' Subsurface Weight: SSS Lab "
            "renders them as plain diffuse for the node groups by itself)"
        )
    warnings, notes = [], []
    extra = {}
    aov = None
    if THICKNESS in passes:
        aov = thickness_aov_name(scene)
        convention, missing = thickness_setup(scene, materials, aov)
        extra = {"thickness_aov": aov, "thickness_convention": convention}
        warnings += [f"{name}: no thickness map feeds the AOV {aov!r}; its thickness reads 0" for name in missing]
    warnings += unmodelled
    desc = describe_scene(scene, materials, **extra)
    changed, index_warnings = _set_pass_indices(materials)
    warnings += index_warnings
    enabled = _enable_passes(layer, [n for n in passes if n != THICKNESS], aov)
    notes += _keep_weights(materials)
    if not scene.render.use_lock_interface:
        scene.render.use_lock_interface = True
        notes.append("Lock Interface switched on: SSS Lab changes the materials' Subsurface Weight while rendering")
    notes.append(
        f"at render time the {len(materials)} subsurface material(s) render as plain diffuse (Subsurface Weight 0) "
        "and get their weights back after the render"
    )
    scale = screen_scales(scene, desc) if per_material else {}
    return PreparedScene(
        layer=layer,
        desc=desc,
        pixels_per_unit=scale,
        materials=materials,
        passes_enabled=enabled,
        pass_indices=changed,
        notes=notes,
        warnings=warnings,
    )
