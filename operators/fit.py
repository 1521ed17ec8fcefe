"""``bpy.ops.sss_lab.fit_to_cycles`` and ``clear_fit``: the fit to Cycles (``blender.calibrate``) for the panel;
the fit's stored values are read and cleared through ``blender.stored``.

Fit to Cycles runs as a modal job (``operators/modal.py``): the random-walk render, the passes and
the fit are its three steps (five when it renders more samples for fits that did not hold), with
progress in the status bar; Esc cancels between steps and leaves
every material as it was (the fitted values are written only after the last step)."""

from __future__ import annotations

import bpy

from ..blender.calibrate import calibrate_job
from ..blender.stored import PREFIX, clear_fit
from ..core.study.fit import BUDGET, MAX_SAMPLES, REFERENCE_SAMPLES
from .modal import DialogModalJob


class SSS_LAB_OT_fit_to_cycles(DialogModalJob, bpy.types.Operator):
    """Fit each subsurface material's parameters to a short Cycles random-walk render of this view (Esc: cancel)"""

    bl_idname = "sss_lab.fit_to_cycles"
    bl_label = "Fit to Cycles"
    bl_options = {"REGISTER", "UNDO"}
    job_label = "Fit to Cycles"

    samples: bpy.props.IntProperty(
        name="Samples", min=1, default=32, description="Cycles random-walk samples of the image the fit is made on"
    )
    max_samples: bpy.props.IntProperty(
        name="Up to",
        min=1,
        default=MAX_SAMPLES,
        description="For the fits that do not hold on held-out pixels: render again up to this many samples in"
        f" all, while the fit costs at most {100 * BUDGET:g} % of a {REFERENCE_SAMPLES}-sample render"
        " (at most Samples: never)",
    )

    # Hidden flags of the dialog-then-modal run (``DialogModalJob``).
    confirmed: bpy.props.BoolProperty(options={"HIDDEN", "SKIP_SAVE"})
    from_dialog: bpy.props.BoolProperty(options={"HIDDEN", "SKIP_SAVE"})

    def dialog_settings(self) -> dict:
        return dict(samples=self.samples, max_samples=self.max_samples)

    def new_job(self, context):
        return calibrate_job(
            context.scene, samples=self.samples, max_samples=max(self.max_samples, self.samples), log=print
        )

    def job_done(self, context, result):
        for line in result["problems"]:
            self.report({"WARNING"}, line)
        for r in result["results"]:
            errors = f"{r['heldout_before']:.3g} -> {r['heldout_after']:.3g}"
            self.report({"INFO"}, f"{r['material']} {r['technique']}: held-out error {errors}")
        if not result["results"]:
            self.report({"ERROR"}, "no material could be fitted (see the warnings); nothing changed")
            return {"CANCELLED"}
        return {"FINISHED"}


class SSS_LAB_OT_clear_fit(bpy.types.Operator):
    """Remove the values fitted to Cycles from the active material (the unfitted mapping is used again)"""

    bl_idname = "sss_lab.clear_fit"
    bl_label = "Clear Fit"
    bl_options = {"REGISTER", "UNDO"}

    technique: bpy.props.StringProperty(name="Technique", default="", description="Only this technique's fit")

    @classmethod
    def poll(cls, context):
        mat = getattr(context, "material", None) or getattr(context.object, "active_material", None)
        return mat is not None and any(k.startswith(PREFIX) for k in mat.keys())

    def execute(self, context):
        mat = getattr(context, "material", None) or context.object.active_material
        removed = clear_fit(mat, self.technique or None)
        self.report({"INFO"}, f"{mat.name}: {len(removed)} fitted value(s) removed")
        return {"FINISHED"}


classes = (SSS_LAB_OT_fit_to_cycles, SSS_LAB_OT_clear_fit)
