"""The SSS Lab panel in the Properties editor (Render tab)."""

from __future__ import annotations

import bpy

from ..blender.calibrate import PREFIX, fit_key
from ..core.fit_params import FIT_PARAMETERS


def draw_technique_parameters(layout, settings) -> None:
    """The chosen technique's parameters (their defaults come from ``core/mapping.py``)."""
    col = layout.column(align=True)
    if settings.technique == "sta":
        col.prop(settings, "sta_distortion")
        col.prop(settings, "sta_power")
        col.prop(settings, "sta_scale")
        col.prop(settings, "sta_ambient")
        layout.prop(settings, "sta_falloff")
    elif settings.technique == "ssss":
        layout.prop(settings, "ssss_taps", expand=True)
        layout.prop(settings, "ssss_kernel")
    else:
        col.prop(settings, "burley_samples")
        col.prop(settings, "burley_random_rotation")
    if settings.technique != "sta":
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
