"""Apply a material preset (``core/presets.py``) to the active material's Principled BSDF."""

from __future__ import annotations

import bpy

from ..core.presets import PRESETS, get_preset
from .describe import principled_node

_ITEMS = [(p.name, p.label, ("Measured: " if p.measured else "Artistic: ") + p.source) for p in PRESETS.values()]


def apply_preset(material, name: str, unit_scale_m: float = 1.0) -> dict:
    """Set the subsurface inputs of ``material``'s Principled BSDF to preset ``name``.

    Lengths become scene units with ``unit_scale_m`` metres per unit (the scene's Unit Scale).
    Returns the values set. ValueError when the material has no Principled BSDF, or an input is
    driven by a link (the preset would not show).
    """
    preset = get_preset(name)
    node = principled_node(material)
    if node is None:
        what = "no material" if material is None else f"material {material.name!r} has no Principled BSDF"
        raise ValueError(f"cannot apply the {preset.label} preset: {what}")
    values = preset.principled_values(unit_scale_m)
    linked = [n for n in values if node.inputs[n].is_linked]
    if linked:
        raise ValueError(
            f"material {material.name!r}: {', '.join(linked)} driven by a link; disconnect it to use the "
            f"{preset.label} preset"
        )
    for socket, value in values.items():
        node.inputs[socket].default_value = value
    return values


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
