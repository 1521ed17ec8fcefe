"""``bpy.ops.sss_lab.compare``: compare with Cycles (``blender.compare``) and write the report."""

from __future__ import annotations

import os

import bpy

from ..blender.compare import CompareSettings, compare


class SSS_LAB_OT_compare(bpy.types.Operator):
    """Compare each technique with Cycles random walk on this scene and write a report"""

    bl_idname = "sss_lab.compare"
    bl_label = "Compare with Cycles"
    bl_options = {"REGISTER"}

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

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        out_dir = bpy.path.abspath(self.directory)
        # An unsaved file has no folder for "//": abspath would quietly use the working directory.
        if not out_dir or (self.directory.startswith("//") and not bpy.data.filepath):
            self.report({"ERROR"}, "Save the .blend file first, or choose an absolute report folder")
            return {"CANCELLED"}
        settings = CompareSettings(reference_samples=self.reference_samples, pass_samples=self.pass_samples)
        wm = context.window_manager
        steps = iter(range(10_000))
        wm.progress_begin(0, 100)

        def log(line):
            print(line)
            wm.progress_update(min(next(steps), 100))

        try:
            data = compare(context.scene, out_dir, settings, log=log)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        best = [e for e in data["entries"] if e["name"] in data["pareto"] and e["kind"] == "technique"]
        for e in best:
            self.report(
                {"INFO"}, f"{e['name']}: rel. RMSE {e['metrics']['rel_rmse']:.4f}, {e['time_s']['total']:.2f} s"
            )
        level = {"INFO"} if data["complete"] else {"WARNING"}
        self.report(
            level,
            f"Report: {os.path.join(out_dir, 'report.html')}"
            + ("" if data["complete"] else " (incomplete: " + "; ".join(data["notes"]) + ")"),
        )
        return {"FINISHED"}


classes = (SSS_LAB_OT_compare,)
