"""Apply a material preset (``core/study/presets.py``) to the active material's Principled BSDF."""

from __future__ import annotations

import bpy

from ..blender.presets import apply_preset
from ..core.study.presets import PRESETS

_ITEMS = [(p.name, p.label, ("Measured: " if p.measured else "Artistic: ") + p.source) for p in PRESETS.values()]


class SSS_LAB_OT_apply_preset(bpy.types.Operator):
    """Set the active material's subsurface values (Base Color, Radius, Scale, Weight 1) to a preset"""

    bl_idname = "sss_lab.apply_preset"
    bl_label = "Apply Material Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: bpy.props.EnumProperty(name="Preset", items=_ITEMS, default="skin")

    @classmethod
    def poll(cls, context):
        obj = context.object
        if obj is None or obj.active_material is None:
            cls.poll_message_set("Select an object with a material")
            return False
        return True

    def execute(self, context):
        material = context.object.active_material
        preset = PRESETS[self.preset]
        try:
            values = apply_preset(material, self.preset, context.scene.unit_settings.scale_length)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        radius = ", ".join(f"{v:.3g}" for v in values["Subsurface Radius"])
        self.report(
            {"INFO"},
            f"{material.name}: {preset.label} preset (radius {radius}, scale {values['Subsurface Scale']:.4g}); "
            f"source: {preset.source}",
        )
        return {"FINISHED"}


classes = (SSS_LAB_OT_apply_preset,)
