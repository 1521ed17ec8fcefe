"""Scan the scene: which materials scatter, with which method and radius.

The first question before any technique runs; the answer drives what the other jobs model
(only materials with Subsurface Weight > 0 scatter).
"""

from __future__ import annotations

import bpy

from .describe import sss_materials


def scan_report(scene) -> list[str]:
    """One line per subsurface material of ``scene``, or one line saying there is none."""
    materials = sss_materials(scene)
    if not materials:
        return [f"Scene {scene.name!r}: no material with subsurface scattering (Subsurface Weight > 0)"]
    lines = [f"Scene {scene.name!r}: {len(materials)} subsurface material(s)"]
    for m in materials:
        radius = ", ".join(f"{r:.4g}" for r in m.radius)
        lines.append(f"  {m.name}: method {m.method}, weight {m.subsurface_weight:.3g}, radius x scale ({radius})")
    return lines


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
