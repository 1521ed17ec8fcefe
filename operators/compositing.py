"""``bpy.ops.sss_lab.setup_compositor``: the compositor set-up (``blender.compositor``) for the panel."""

from __future__ import annotations

import bpy

from ..blender import compat
from ..blender.compositor import setup_compositor
from ..core.techniques import DEFAULT_TECHNIQUE, TECHNIQUES

#: A technique dropdown whose first entry defers to the panel's choice (Set Up Compositor, Apply).
TECHNIQUE_ITEMS = [("PANEL", "From Panel", "The technique chosen in the SSS Lab panel")] + [
    (name, t.label, t.description) for name, t in TECHNIQUES.items()
]


class SSS_LAB_OT_setup_compositor(bpy.types.Operator):
    """Insert the technique's node groups after Render Layers; your nodes are kept, a new set-up replaces SSS Lab's"""

    bl_idname = "sss_lab.setup_compositor"
    bl_label = "Set Up Compositor"
    bl_options = {"REGISTER", "UNDO"}

    technique: bpy.props.EnumProperty(name="Technique", items=TECHNIQUE_ITEMS, default="PANEL", options={"SKIP_SAVE"})

    @classmethod
    def poll(cls, context):
        missing = compat.compositor_groups_missing()
        if missing is not None:
            cls.poll_message_set(missing)
            return False
        return context.scene is not None

    def execute(self, context):
        scene = context.scene
        settings = getattr(scene, "sss_lab", None)
        technique = self.technique
        if technique == "PANEL":
            technique = settings.technique if settings is not None else DEFAULT_TECHNIQUE
        options = {}
        if settings is not None:
            options = dict(settings.technique_options(technique))
            options["albedo_mode"] = settings.albedo_mode
        try:
            report = setup_compositor(scene, technique, options=options, view_layer=context.view_layer)
        except (ValueError, compat.MissingFeature) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for line in report["warnings"]:
            self.report({"WARNING"}, line)
        for line in report["notes"]:
            self.report({"INFO"}, line)
        extra = []
        if report["passes_enabled"]:
            extra.append("passes on: " + ", ".join(report["passes_enabled"]))
        if report["pass_indices"]:
            extra.append("pass indices: " + ", ".join(report["pass_indices"]))
        self.report(
            {"INFO"},
            f"{technique}: {len(report['nodes'])} node(s) in {report['tree']!r} ({', '.join(report['groups'])})"
            + (f"; {'; '.join(extra)}" if extra else ""),
        )
        return {"FINISHED"}


classes = (SSS_LAB_OT_setup_compositor,)
