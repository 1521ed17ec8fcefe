"""Scan the scene: which materials scatter, with which method and radius.

The first question before any technique runs; the answer drives what the other jobs model
(only materials with Subsurface Weight > 0 scatter).
"""

from __future__ import annotations

import bpy

from ..blender.scan import recommendation, scan_report
from ..core.base.errors import SSSLabError


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


class SSS_LAB_OT_recommend(bpy.types.Operator):
    """Render small passes once and say which technique and quality to use per material (apply's auto)"""

    bl_idname = "sss_lab.recommend"
    bl_label = "Recommend"
    bl_options = {"REGISTER"}

    max_error: bpy.props.FloatProperty(
        name="Error Margin",
        min=0.0,
        max=1.0,
        default=0.03,
        subtype="FACTOR",
        description="How much more error than the best technique the cheapest acceptable one may have",
    )
    rungs: bpy.props.BoolProperty(
        name="Quality Rungs",
        default=False,
        description="Also consider each technique's cheaper qualities (saves more time, further from the best)",
    )

    def execute(self, context):
        try:
            lines, plan = recommendation(context.scene, max_error=self.max_error, rungs=self.rungs, log=None)
        except (SSSLabError, ValueError, OSError) as exc:
            self.report({"ERROR"}, " ".join(str(exc).split()))
            return {"CANCELLED"}
        if plan is None:
            self.report({"WARNING"}, lines[0] if lines else "No material with subsurface scattering")
            return {"CANCELLED"}
        for c in plan.choices:  # the verdict first, one line per material
            self.report({"INFO"}, f"{c.features.name}: use {c.chosen} ({c.reason})")
        for line in lines:
            self.report({"INFO"}, line.strip())
        return {"FINISHED"}


classes = (SSS_LAB_OT_scan_scene, SSS_LAB_OT_recommend)
