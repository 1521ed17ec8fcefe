"""Scan the scene: which materials scatter, with which method and radius.

The first question before any technique runs; the answer drives what the other jobs model
(only materials with Subsurface Weight > 0 scatter).
"""

from __future__ import annotations

import bpy

from ..blender.scan import scan_report


class SSS_LAB_OT_scan_scene(bpy.types.Operator):
    """List the scene's materials with subsurface scattering and their parameters"""

    bl_idname = "sss_lab.scan_scene"
    bl_label = "Scan Scene"
    bl_options = {"REGISTER"}

    def execute(self, context):
        lines = scan_report(context.scene)
        for line in lines:
            self.report({"INFO"}, line)
        return {"FINISHED"}


classes = (SSS_LAB_OT_scan_scene,)
