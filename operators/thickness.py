"""``bpy.ops.sss_lab.bake_thickness``: the thickness bake (``blender.bake``) for the panel.

Modal in the UI (``operators/modal.py``: one object per timer step, Esc cancels between
objects, Blender's progress API and status text), blocking headless. Undo: the operator
registers an undo step (attributes, images, material nodes); the image files written to disk
stay.
"""

from __future__ import annotations

import bpy

from ..blender.bake import BakeResult, ThicknessBake, bake_job, settings_from_scene
from .modal import ModalJob


class SSSLabObjectName(bpy.types.PropertyGroup):
    """One object name (``name``) for the operator's ``objects`` list."""


class SSS_LAB_OT_bake_thickness(ModalJob, bpy.types.Operator):
    """Bake a thickness map (inverted-normal ambient occlusion) for the selected meshes (Esc: cancel between objects)"""

    # Undo removes the baked attributes, images and material nodes, not image files on disk.

    bl_idname = "sss_lab.bake_thickness"
    bl_label = "Bake Thickness"
    bl_options = {"REGISTER", "UNDO"}
    job_label = "Thickness Bake"

    objects: bpy.props.CollectionProperty(
        type=SSSLabObjectName,
        name="Objects",
        description="Objects to bake, by name (empty: the selected objects)",
        options={"SKIP_SAVE", "HIDDEN"},
    )

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to bake thickness")
            return False
        return context.scene is not None

    def new_job(self, context):
        names = [item.name for item in self.objects] or None
        self._batch = ThicknessBake(context, names, settings_from_scene(context.scene))
        return bake_job(self._batch)

    def job_done(self, context, results):
        return self._report(results)

    def job_cancelled(self, context):
        # Objects baked before Esc keep their maps: reported, and FINISHED (an undo step) if any.
        self.report({"WARNING"}, "Thickness bake cancelled")
        return self._report(self._batch.results)

    def _report(self, results: list[BakeResult]):
        for r in results:
            level = {"failed": "ERROR", "skipped": "WARNING", "cancelled": "WARNING"}.get(r.status, "INFO")
            self.report({level}, str(r))
        baked = [r for r in results if r.status in ("baked", "shared")]
        return {"FINISHED"} if baked else {"CANCELLED"}


classes = (SSSLabObjectName, SSS_LAB_OT_bake_thickness)
