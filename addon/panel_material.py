"""The SSS Lab panel of the Material tab: what acts on one material (the subsurface presets and
the values fitted to Cycles), beside Blender's own Surface and Settings panels."""

from __future__ import annotations

import bpy


class SSS_LAB_PT_material(bpy.types.Panel):
    bl_label = "SSS Lab"
    bl_idname = "SSS_LAB_PT_material"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.material is not None

    def draw(self, context):
        from .panels import draw_fit, split

        layout = split(self.layout)
        layout.operator_menu_enum("sss_lab.apply_preset", "preset", text="Subsurface Preset", icon="PRESET")
        draw_fit(layout.column(), context.material)


classes = (SSS_LAB_PT_material,)
