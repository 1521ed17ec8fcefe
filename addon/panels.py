"""The SSS Lab panel in the Properties editor (Render tab), laid out as Cycles lays out its own:
a parent panel with the technique, then one sub-panel per step of the workflow, in the order a
user takes them (parameters, thickness bake, render passes, apply, compositor, compare), every
property row split (label left, value right).

The material's own settings (presets, values fitted to Cycles) are in the Material tab
(``panel_material.py``); the Thickness Bake sub-panel is ``panel_bake.py``.
"""

from __future__ import annotations

import bpy

from ..blender.stored import PREFIX, fit_key
from ..core.pipeline.fit_params import FIT_PARAMETERS
from ..core.techniques.registry import TECHNIQUES


def draw_technique_parameters(layout, settings) -> None:
    """The chosen technique's parameters: one row per parameter of its spec (defaults: its
    function's signature), and the albedo mode for a technique that scatters."""
    spec = TECHNIQUES.get_spec(settings.technique)
    group = getattr(settings, spec.name)
    col = layout.column(align=True)
    for p in spec.params:
        if p.choices and p.type is int:
            layout.prop(group, p.name, expand=True)  # a few counts: buttons side by side
        elif p.choices:
            layout.prop(group, p.name)
        else:
            col.prop(group, p.name)
    if spec.scatters:
        layout.prop(settings, "albedo_mode")


def draw_fit(layout, material) -> None:
    """Rows of the fitted values of ``material`` (editable), with Clear Fit."""
    keys = [k for k in material.keys() if k.startswith(PREFIX)]
    if not keys:
        layout.label(text=f"{material.name}: not fitted (Fit to Cycles)")
        return
    for technique, names in FIT_PARAMETERS.items():
        shown = [n for n in names if fit_key(technique, n) in keys]
        if not shown:
            continue
        box = layout.box()
        row = box.row()
        row.label(text=f"{material.name}: {technique} fit")
        op = row.operator("sss_lab.clear_fit", text="", icon="X")
        op.technique = technique
        for name in shown:
            box.prop(material, f'["{fit_key(technique, name)}"]', text=name.replace("_", " ").title())


def split(layout):
    """``layout`` with property split on (label left, value right) and no animation decorators."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


def _note(layout, text: str) -> None:
    col = layout.column(align=True)
    col.scale_y = 0.8
    col.label(text=text, icon="INFO")


def draw_setup_compositor(layout, settings=None) -> None:
    """The Set Up Compositor button (with the Burley route when the technique is Burley); on a
    Blender that cannot run the node groups (4.5) it is greyed out by its poll (the tooltip has the
    whole reason) and two lines say what that version lacks."""
    from ..blender import compat

    if settings is not None and settings.technique == "burley":
        layout.prop(settings, "compositor_route")
    layout.operator("sss_lab.setup_compositor", icon="NODE_COMPOSITING")
    if compat.compositor_groups_missing() is not None:
        _note(layout, f"Blender {bpy.app.version_string.split()[0]}: no Convolve node, no compositor groups")
        _note(layout, "Use Render Passes and Apply (same techniques)")


class _Panel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"


class SSS_LAB_PT_main(_Panel, bpy.types.Panel):
    bl_label = "SSS Lab"
    bl_idname = "SSS_LAB_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = split(self.layout)
        layout.prop(context.scene.sss_lab, "technique")
        layout.operator("sss_lab.scan_scene", icon="VIEWZOOM")
        layout.operator("sss_lab.recommend", icon="LIGHT")


class _Step(_Panel):
    bl_parent_id = "SSS_LAB_PT_main"


class SSS_LAB_PT_parameters(_Step, bpy.types.Panel):
    bl_label = "Parameters"
    bl_idname = "SSS_LAB_PT_parameters"
    bl_order = 0

    def draw(self, context):
        draw_technique_parameters(split(self.layout), context.scene.sss_lab)


# Order 1: Thickness Bake (panel_bake.py).


class SSS_LAB_PT_render(_Step, bpy.types.Panel):
    bl_label = "Render Passes"
    bl_idname = "SSS_LAB_PT_render"
    bl_order = 2

    def draw(self, context):
        layout = split(self.layout)
        settings = context.scene.sss_lab
        layout.prop(settings, "output_dir")
        layout.prop(settings, "render_samples")
        layout.prop(settings, "render_all")
        layout.operator("sss_lab.render_passes", icon="RENDER_STILL")
        _note(layout, "Esc cancels between frames; finished frames stay.")


class SSS_LAB_PT_apply(_Step, bpy.types.Panel):
    bl_label = "Apply"
    bl_idname = "SSS_LAB_PT_apply"
    bl_order = 3

    def draw(self, context):
        layout = split(self.layout)
        layout.prop(context.scene.sss_lab, "passes_file")
        layout.operator("sss_lab.apply", icon="IMAGE_DATA")
        from ..blender import prepare

        if prepare.running():
            _note(
                layout, "Compiling the kernels in the background (once per version): until then Apply waits for them."
            )


class SSS_LAB_PT_compositor(_Step, bpy.types.Panel):
    bl_label = "Compositor"
    bl_idname = "SSS_LAB_PT_compositor"
    bl_order = 4
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = split(self.layout)
        draw_setup_compositor(layout, getattr(context.scene, "sss_lab", None))


class SSS_LAB_PT_compare(_Step, bpy.types.Panel):
    bl_label = "Compare with Cycles"
    bl_idname = "SSS_LAB_PT_compare"
    bl_order = 5

    def draw(self, context):
        layout = split(self.layout)
        layout.operator("sss_lab.compare", icon="SORTTIME")
        _note(layout, "Esc cancels between renders; rendered references stay cached.")
        layout.operator("sss_lab.fit_to_cycles", icon="DRIVER_DISTANCE")
        layout.operator("sss_lab.match_eevee", icon="SHADING_RENDERED")
        layout.operator("sss_lab.remove_eevee_match", icon="X")
        layout.operator("sss_lab.export_profiles", icon="EXPORT")


classes = (
    SSS_LAB_PT_main,
    SSS_LAB_PT_parameters,
    SSS_LAB_PT_render,
    SSS_LAB_PT_apply,
    SSS_LAB_PT_compositor,
    SSS_LAB_PT_compare,
)
