"""``bpy.ops.sss_lab.match_eevee`` and ``remove_eevee_match``: EEVEE matched to Cycles per material
(``blender.match_eevee``) from the panel.

Match EEVEE runs as a modal job (``operators/modal.py``): one step per render, with progress in
the status bar; Esc cancels between renders and takes out every branch it had added. One undo
step for the whole match; Remove EEVEE Match takes every match out in one step (undoable)."""

from __future__ import annotations

import bpy

from ..blender.match_eevee import EEVEE_TAG, MATCH_KEY, MatchSettings, match_eevee_job, remove_match
from .modal import DialogModalJob


def _matched(material) -> bool:
    tree = getattr(material, "node_tree", None)
    return MATCH_KEY in material.keys() or (tree is not None and any(n.get(EEVEE_TAG) for n in tree.nodes))


class SSS_LAB_OT_match_eevee(DialogModalJob, bpy.types.Operator):
    """Match EEVEE's subsurface scattering to Cycles random walk per material, in an EEVEE-only branch (Esc: cancel)"""

    bl_idname = "sss_lab.match_eevee"
    bl_label = "Match EEVEE to Cycles"
    bl_options = {"REGISTER", "UNDO"}
    job_label = "Match EEVEE"

    cycles_samples: bpy.props.IntProperty(
        name="Cycles Samples",
        min=1,
        default=MatchSettings.cycles_samples,
        description="Cycles random-walk samples of the SSS effect EEVEE is matched to",
    )
    confirmed: bpy.props.BoolProperty(options={"HIDDEN", "SKIP_SAVE"})
    from_dialog: bpy.props.BoolProperty(options={"HIDDEN", "SKIP_SAVE"})

    def dialog_settings(self) -> dict:
        return dict(cycles_samples=self.cycles_samples)

    def new_job(self, context):
        return match_eevee_job(context.scene, MatchSettings(cycles_samples=self.cycles_samples), log=print)

    def job_done(self, context, result):
        matched = 0
        for name, r in result["materials"].items():
            if r["skipped"]:
                self.report({"WARNING"}, f"{name}: no EEVEE branch ({r['skipped']})")
                continue
            matched += 1
            self.report(
                {"INFO"},
                f"{name}: EEVEE reproduces {100 * r['removed_after']:.0f} % of Cycles' SSS effect"
                f" (as authored {100 * (r['removed_before'] or 0):.0f} %)",
            )
        if not matched:
            self.report({"WARNING"}, "no material was matched; nothing changed")
            return {"CANCELLED"}
        return {"FINISHED"}


class SSS_LAB_OT_remove_eevee_match(bpy.types.Operator):
    """Remove the EEVEE-only branches Match EEVEE added (EEVEE renders the materials as authored again)"""

    bl_idname = "sss_lab.remove_eevee_match"
    bl_label = "Remove EEVEE Match"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return any(_matched(m) for m in bpy.data.materials)

    def execute(self, context):
        removed = [m.name for m in bpy.data.materials if remove_match(m)]
        self.report({"INFO"}, f"EEVEE match removed from {len(removed)} material(s)")
        return {"FINISHED"}


classes = (SSS_LAB_OT_match_eevee, SSS_LAB_OT_remove_eevee_match)
