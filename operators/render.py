"""``bpy.ops.sss_lab.render_passes``: render the passes (``blender.render_passes``) for the panel,
one frame per step (modal in the interface: progress, status text, Esc between frames)."""

from __future__ import annotations

import bpy

from ..blender.render_passes import NoSubsurfaceError, render_passes_job, resolve_folder
from ..core.techniques.registry import TECHNIQUES
from .modal import ModalJob

_TECHNIQUE_FLAGS = [(name, t.label, t.description) for name, t in TECHNIQUES.items()]


class SSS_LAB_OT_render_passes(ModalJob, bpy.types.Operator):
    """Render the passes the techniques need into a multilayer EXR per frame (Esc: cancel between frames)"""

    bl_idname = "sss_lab.render_passes"
    bl_label = "Render Passes"
    # Undo: it sets the panel's Passes file (the files written stay).
    bl_options = {"REGISTER", "UNDO"}
    job_label = "Render Passes"

    directory: bpy.props.StringProperty(
        name="Output Folder",
        description="Folder for passes_####.exr and .json (empty: the panel's Output folder)",
        default="",
        subtype="DIR_PATH",
        options={"SKIP_SAVE"},
    )
    techniques: bpy.props.EnumProperty(
        name="Techniques",
        description="Techniques whose passes to render (none: the panel's choice)",
        items=_TECHNIQUE_FLAGS,
        options={"ENUM_FLAG", "SKIP_SAVE"},
        default=set(),
    )
    samples: bpy.props.IntProperty(
        name="Samples",
        description="Cycles samples (-1: the panel's; 0: the scene's)",
        default=-1,
        min=-1,
        options={"SKIP_SAVE"},
    )
    use_frame_range: bpy.props.BoolProperty(
        name="Frame Range",
        description="Render every frame of the scene's frame range (else the current frame)",
        default=False,
        options={"SKIP_SAVE"},
    )
    overwrite: bpy.props.BoolProperty(
        name="Overwrite",
        description="Replace passes files already in the folder",
        default=True,
        options={"SKIP_SAVE"},
    )

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def new_job(self, context):
        scene = context.scene
        settings = getattr(scene, "sss_lab", None)
        self._techniques = sorted(self.techniques, key=list(TECHNIQUES).index) or (
            settings.render_techniques() if settings is not None else list(TECHNIQUES)
        )
        samples = self.samples if self.samples >= 0 else (settings.render_samples if settings is not None else 0)
        frames = list(range(scene.frame_start, scene.frame_end + 1)) if self.use_frame_range else None
        self._notes = []

        def log(line: str):
            print(f"render-passes: {line}", flush=True)
            if not line.startswith("[") and not line.startswith("frame ") and not line.startswith("Saved:"):
                self._notes.append(line)

        self._folder = resolve_folder(self.directory or (settings.output_dir if settings is not None else ""))
        return render_passes_job(
            scene,
            self._folder,
            techniques=self._techniques,
            frames=frames,
            samples=samples or None,
            overwrite=self.overwrite,
            log=log,
        )

    def job_failed(self, exc):
        if isinstance(exc, NoSubsurfaceError):  # nothing to do: said, not an error
            self.report({"WARNING"}, str(exc))
            return {"CANCELLED"}
        return ModalJob.job_failed(self, exc)

    def job_done(self, context, paths):
        for line in self._notes:
            warn = "thickness 0" in line or "not followed per pixel" in line
            self.report({"WARNING"} if warn else {"INFO"}, line)
        exrs = [p for p in paths if p.endswith(".exr")]
        settings = getattr(context.scene, "sss_lab", None)
        if settings is not None and exrs:
            settings.passes_file = exrs[-1]
        self.report(
            {"INFO"}, f"Rendered the {', '.join(self._techniques)} passes of {len(exrs)} frame(s) into {self._folder}"
        )
        return {"FINISHED"}


classes = (SSS_LAB_OT_render_passes,)
