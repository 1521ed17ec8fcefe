"""The compositor set-up: ``setup_compositor``, the plain function, and
``bpy.ops.sss_lab.setup_compositor``, which runs it for the panel.

The set-up joins the scene side (``blender.compositor.prepare_scene``: passes, pass indices, the
scene description; its docstring lists what the set-up changes) and the node side
(``nodes.setup.insert_chain``: the technique's groups wired after Render Layers).
"""

from __future__ import annotations

import bpy

from ..blender import compat
from ..blender.compositor import prepare_scene
from ..core.techniques.registry import DEFAULT_TECHNIQUE, TECHNIQUES
from ..nodes import setup as chain

#: A technique dropdown whose first entry defers to the panel's choice (Set Up Compositor, Apply).
TECHNIQUE_ITEMS = [("PANEL", "From Panel", "The technique chosen in the SSS Lab panel")] + [
    (name, t.label, t.description) for name, t in TECHNIQUES.items()
]
#: Set Up Compositor offers only the techniques that have node groups (``nodes.setup.BUILDERS``).
COMPOSITOR_ITEMS = [TECHNIQUE_ITEMS[0]] + [item for item in TECHNIQUE_ITEMS[1:] if item[0] in chain.BUILDERS]


def setup_compositor(scene, technique: str, *, options: dict | None = None, view_layer=None) -> dict:
    """Insert ``technique``'s node groups into ``scene``'s compositor; returns a report dict
    (technique, groups, nodes, passes_enabled, pass_indices, notes, warnings).

    ``options``: technique parameters under ``core``'s names (and ``albedo_mode``).
    Raises ValueError (no camera, no subsurface material) with a clear message, and
    ``compat.MissingFeature`` on a Blender whose compositor cannot run the groups (4.5), before
    changing anything.
    """
    compat.require_compositor_groups()
    builder = chain.builder(technique)  # ValueError naming why for a technique without node groups
    prepared = prepare_scene(
        scene,
        passes=builder.passes,
        per_material=builder.per_material,
        unmodelled=builder.unmodelled(options or {}),
        view_layer=view_layer,
    )
    scale = prepared.pixels_per_unit
    inserted = chain.insert_chain(
        scene,
        prepared.layer,
        technique=technique,
        desc=prepared.desc,
        options=options,
        pixels_per_unit=scale,
    )
    return {
        "technique": technique,
        "tree": inserted["tree"],
        "groups": inserted["groups"],
        "nodes": inserted["nodes"],
        "removed": inserted["removed"],
        "passes_enabled": prepared.passes_enabled,
        "pass_indices": prepared.pass_indices,
        "pixels_per_unit": {m.name: scale[m.index] for m in prepared.materials if m.index in scale},
        "notes": prepared.notes + inserted["notes"],
        "warnings": prepared.warnings,
    }


class SSS_LAB_OT_setup_compositor(bpy.types.Operator):
    """Insert the technique's node groups after Render Layers; your nodes are kept, a new set-up replaces SSS Lab's"""

    bl_idname = "sss_lab.setup_compositor"
    bl_label = "Set Up Compositor"
    bl_options = {"REGISTER", "UNDO"}

    technique: bpy.props.EnumProperty(name="Technique", items=COMPOSITOR_ITEMS, default="PANEL", options={"SKIP_SAVE"})

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
            if technique == "burley":
                options["route"] = settings.compositor_route
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
