"""The SSS Lab panel in the Properties editor (Render tab)."""

from __future__ import annotations

import bpy


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


classes = (SSS_LAB_PT_main,)
