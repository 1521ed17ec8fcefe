"""``bpy.ops.sss_lab.compare``: compare with Cycles (``blender.compare``) and write the report,
one render per step (modal in the interface: progress, status text, Esc between renders)."""

from __future__ import annotations

import os

import bpy

from ..blender.compare import CompareSettings, compare_job
from ..core.study.report_schema import Report
from .modal import DialogModalJob


class SSS_LAB_OT_compare(DialogModalJob, bpy.types.Operator):
    """Compare each technique with Cycles random walk on this scene and write a report (Esc: cancel between renders)"""

    bl_idname = "sss_lab.compare"
    bl_label = "Compare with Cycles"
    bl_options = {"REGISTER"}
    job_label = "Compare"

    directory: bpy.props.StringProperty(
        name="Report Folder",
        description="Folder for the report (metrics.json, report.html, images)",
        subtype="DIR_PATH",
        default="//sss_lab_report/",
        options={"PATH_SUPPORTS_BLEND_RELATIVE"},
    )
    reference_samples: bpy.props.IntProperty(
        name="Reference Samples",
        min=1,
        default=CompareSettings.reference_samples,
        description="Cycles samples of the random-walk reference",
    )
    pass_samples: bpy.props.IntProperty(
        name="Pass Samples",
        min=1,
        default=CompareSettings.pass_samples,
        description="Cycles samples of the passes the techniques run on",
    )
    eevee: bpy.props.BoolProperty(
        name="Include EEVEE",
        default=CompareSettings.eevee,
        description="Also render EEVEE with and without scattering and score it beside the techniques"
        " (its image, and its SSS effect against Cycles')",
    )
    # Hidden flags of the dialog-then-modal run (``DialogModalJob``).
    confirmed: bpy.props.BoolProperty(options={"HIDDEN", "SKIP_SAVE"})
    from_dialog: bpy.props.BoolProperty(options={"HIDDEN", "SKIP_SAVE"})

    def dialog_settings(self) -> dict:
        return dict(
            directory=self.directory,
            reference_samples=self.reference_samples,
            pass_samples=self.pass_samples,
            eevee=self.eevee,
        )

    def new_job(self, context):
        out_dir = bpy.path.abspath(self.directory)
        # An unsaved file has no folder for "//": abspath would quietly use the working directory.
        if not out_dir or (self.directory.startswith("//") and not bpy.data.filepath):
            raise ValueError("Save the .blend file first, or choose an absolute report folder")
        self._out_dir = out_dir
        settings = CompareSettings(
            reference_samples=self.reference_samples, pass_samples=self.pass_samples, eevee=self.eevee
        )
        return compare_job(context.scene, out_dir, settings, log=print)

    def job_done(self, context, data):
        result = Report.from_dict(data)
        for e in result.best_techniques:
            self.report({"INFO"}, f"{e.name}: rel. RMSE {e.metrics['rel_rmse']:.4f}, {e.time_s['total']:.2f} s")
        eevee = data.get("eevee") or {}
        if eevee.get("error"):
            self.report({"WARNING"}, f"EEVEE left out: {eevee['error']}")
        level = {"INFO"} if result.complete else {"WARNING"}
        self.report(
            level,
            f"Report: {os.path.join(self._out_dir, 'report.html')}"
            + ("" if result.complete else " (incomplete: " + "; ".join(result.notes) + ")"),
        )
        return {"FINISHED"}


classes = (SSS_LAB_OT_compare,)
