"""The Thickness Bake sub-panel of the SSS Lab panel (Properties editor, Render tab)."""

from __future__ import annotations

import bpy

from .panels import split


class SSS_LAB_PT_bake(bpy.types.Panel):
    bl_label = "Thickness Bake"
    bl_idname = "SSS_LAB_PT_bake"
    bl_parent_id = "SSS_LAB_PT_main"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_order = 1  # after the technique's parameters, before Render Passes (panels.py)

    def draw(self, context):
        layout = split(self.layout)
        s = context.scene.sss_lab.bake
        layout.prop(s, "target")
        if s.target == "attribute":  # the ray source measures at the vertices
            layout.prop(s, "source")
        layout.prop(s, "convention")
        col = layout.column(align=True)
        col.prop(s, "samples")
        col.prop(s, "distance")
        layout.prop(s, "only_local")
        if s.target == "attribute":
            layout.prop(s, "attribute_name")
        else:
            col = layout.column(align=True)
            col.prop(s, "resolution")
            col.prop(s, "margin")
            layout.prop(s, "image_format")
            layout.prop(s, "image_folder")
        layout.prop(s, "link_materials")
        if s.link_materials:
            layout.prop(s, "aov_name")
        n = sum(1 for o in context.selected_objects if o.type == "MESH")
        layout.operator("sss_lab.bake_thickness", text=f"Bake Thickness ({n} selected mesh{'es' * (n != 1)})")
        note = layout.column(align=True)
        note.scale_y = 0.8
        note.label(text="Esc cancels between objects.", icon="INFO")
        if s.target == "image":
            note.label(text="Undo cannot delete image files already saved.")


classes = (SSS_LAB_PT_bake,)
