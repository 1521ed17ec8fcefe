"""The SSS Lab panel in the Properties editor (Render tab)."""

from __future__ import annotations

import bpy

from ..blender.calibrate import PREFIX, fit_key
from ..core.fit_params import FIT_PARAMETERS
from ..core.techniques import TECHNIQUES


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


class SSS_LAB_PT_main(bpy.types.Panel):
    bl_label = "SSS Lab"
    bl_idname = "SSS_LAB_PT_main"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        settings = context.scene.sss_lab
        layout.prop(settings, "technique")
        layout.operator("sss_lab.scan_scene", icon="VIEWZOOM")

        box = layout.box()
        box.use_property_split = True
        box.use_property_decorate = False
        draw_technique_parameters(box, settings)

        col = layout.column(align=True)
        col.operator("sss_lab.bake_thickness", icon="MOD_THICKNESS")
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(settings, "output_dir")
        row = layout.row(align=True)
        row.prop(settings, "render_samples")
        row.prop(settings, "render_all", toggle=True)
        layout.operator("sss_lab.render_passes", icon="RENDER_STILL")
        layout.prop(settings, "passes_file")
        layout.operator("sss_lab.apply", icon="IMAGE_DATA")
        layout.operator("sss_lab.setup_compositor", icon="NODE_COMPOSITING")
        layout.operator("sss_lab.compare", icon="SORTTIME")
        layout.operator("sss_lab.fit_to_cycles", icon="DRIVER_DISTANCE")


classes = (SSS_LAB_PT_main,)
