"""``bpy.ops.sss_lab.bake_thickness``: the thickness bake (``blender.bake``) for the panel.

Modal in the UI (one object per timer step, Esc cancels between objects, Blender's progress
API), blocking headless. Undo: the operator registers an undo step (attributes, images,
material nodes); the image files written to disk stay.
"""

from __future__ import annotations

import bpy

from ..blender.bake import BakeResult, ThicknessBake, bake_thickness, settings_from_scene
from ..core.errors import SSSLabError


class SSSLabObjectName(bpy.types.PropertyGroup):
    """One object name (``name``) for the operator's ``objects`` list."""


class SSS_LAB_OT_bake_thickness(bpy.types.Operator):
    """Bake a thickness map (inverted-normal ambient occlusion) for the selected meshes (Esc: cancel between objects)"""

    # Undo removes the baked attributes, images and material nodes, not image files on disk.

    bl_idname = "sss_lab.bake_thickness"
    bl_label = "Bake Thickness"
    bl_options = {"REGISTER", "UNDO"}

    objects: bpy.props.CollectionProperty(
        type=SSSLabObjectName,
        name="Objects",
        description="Objects to bake, by name (empty: the selected objects)",
        options={"SKIP_SAVE", "HIDDEN"},
    )

    _job = None
    _timer = None

    @classmethod
    def poll(cls, context):
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to bake thickness")
            return False
        return context.scene is not None

    def _new_job(self, context):
        names = [item.name for item in self.objects] or None
        return ThicknessBake(context, names, settings_from_scene(context.scene))

    def execute(self, context):
        names = [item.name for item in self.objects] or None
        try:
            results = bake_thickness(context, names, settings_from_scene(context.scene))
        except (SSSLabError, ValueError, OSError) as exc:  # BakeError, a value out of range, a full disk
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        return self._report(results)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            self._job = self._new_job(context)
            self._job.start()
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, max(self._job.total, 1))
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        self._status(context)
        return {"RUNNING_MODAL"}

    def _status(self, context, text: str | None = None):
        if context.workspace is None:
            return
        if text is None and self._job is not None:
            text = f"Baking thickness {self._job.done + 1}/{self._job.total} (Esc: cancel after this object)"
        context.workspace.status_text_set(text)

    def modal(self, context, event):
        if event.type == "ESC":
            self._job.cancel()
            return self._end(context, cancelled=True)
        if event.type == "TIMER":
            try:
                more = self._job.step()
            except BaseException:
                self._end(context)
                raise
            context.window_manager.progress_update(self._job.done)
            if not more:
                return self._end(context)
            self._status(context)
        # Other input is held back: the batch changes the selection between steps.
        return {"RUNNING_MODAL"}

    def cancel(self, context):  # Blender ends the modal operator (file load, window closed)
        if self._job is not None:
            self._job.cancel()
            self._end(context, cancelled=True)

    def _end(self, context, cancelled: bool = False):
        wm = context.window_manager
        try:
            self._job.finish()
        finally:
            if self._timer is not None:
                wm.event_timer_remove(self._timer)
                self._timer = None
            wm.progress_end()
            if context.workspace is not None:
                context.workspace.status_text_set(None)
        results = self._job.results
        self._job = None
        if cancelled:
            self.report({"WARNING"}, "Thickness bake cancelled")
        return self._report(results)

    def _report(self, results: list[BakeResult]):
        for r in results:
            level = {"failed": "ERROR", "skipped": "WARNING", "cancelled": "WARNING"}.get(r.status, "INFO")
            self.report({level}, str(r))
        baked = [r for r in results if r.status in ("baked", "shared")]
        return {"FINISHED"} if baked else {"CANCELLED"}


classes = (SSSLabObjectName, SSS_LAB_OT_bake_thickness)
