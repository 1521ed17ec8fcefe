"""``bpy.ops.sss_lab.apply``: apply a technique to a passes EXR and look at the result.

``blender.apply.apply_passes`` does the work: ``core.pipeline.sequence.apply_file`` (NumPy, the same
code as ``python -m sss_lab apply``) writes ``<stem>.sss.exr`` beside the passes (the input
layers plus ``SSSLab.<technique>.Image`` and ``.SSS``), and the result is loaded as a Blender
image. The operator ``bpy.ops.sss_lab.apply`` takes the technique, its parameters and
the albedo mode from the SSS Lab panel (``scene.sss_lab``) and, by default, the file the last
Render Passes wrote. The scene is not changed; the image is a new data-block, or the same one
reloaded when applied again (the operator registers an undo step for it).
"""

from __future__ import annotations

import bpy

from ..blender.apply import apply_passes
from ..core.pipeline.apply import layer_names
from ..core.techniques.registry import check_technique
from .compositing import TECHNIQUE_ITEMS


def _show(context, image) -> bool:
    """Show ``image`` in an Image Editor of the current screen, if there is one."""
    screen = getattr(context, "screen", None)
    for area in getattr(screen, "areas", ()):
        if area.type == "IMAGE_EDITOR":
            area.spaces.active.image = image
            area.tag_redraw()
            return True
    return False


class SSS_LAB_OT_apply(bpy.types.Operator):
    """Apply the chosen technique to rendered passes (NumPy) and load the result as an image"""

    bl_idname = "sss_lab.apply"
    bl_label = "Apply"
    # Undo: the result is loaded as an Image data-block (the .sss.exr file on disk stays).
    bl_options = {"REGISTER", "UNDO"}

    filepath: bpy.props.StringProperty(
        name="Passes",
        description="Passes EXR (empty: the panel's Passes file, which Render Passes sets)",
        default="",
        subtype="FILE_PATH",
        options={"SKIP_SAVE"},
    )
    technique: bpy.props.EnumProperty(
        name="Technique",
        description="Technique to apply",
        items=TECHNIQUE_ITEMS,
        default="PANEL",
        options={"SKIP_SAVE"},
    )

    @classmethod
    def poll(cls, context):
        return context.scene is not None and getattr(context.scene, "sss_lab", None) is not None

    def execute(self, context):
        settings = context.scene.sss_lab
        technique = settings.technique if self.technique == "PANEL" else self.technique
        path = self.filepath or settings.passes_file
        try:
            options = settings.technique_options(check_technique(technique))
            result, image = apply_passes(path, technique, albedo_mode=settings.albedo_mode, **options)
        except (ValueError, OSError, KeyError, ImportError) as exc:
            message = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
            self.report({"ERROR"}, message)
            return {"CANCELLED"}
        if result.nothing_to_do:
            self.report(
                {"WARNING"},
                f"{result.path}: no material in the scene description scatters light (Subsurface Weight > 0): "
                "nothing written",
            )
            return {"CANCELLED"}
        plan = result.plans[technique]
        for line in plan.explain().splitlines():
            print(f"apply: {line}")
        applied = plan.applied
        names = ", ".join(m.material.name or str(m.material.index) for m in applied) or "none on screen"
        self.report({"INFO"}, f"{technique}: {len(applied)} material(s) computed ({names})")
        if plan.index_warning:
            self.report({"WARNING"}, plan.index_warning)
        if plan.nonfinite_pixels:
            self.report({"WARNING"}, f"{plan.nonfinite_pixels} pixels with NaN/Inf inputs left as they are")
        shown = _show(context, image) if image is not None else False
        where = "shown in the Image Editor" if shown else "open it in an Image Editor"
        self.report(
            {"INFO"},
            f"Saved: '{result.out_path}'; image {image.name!r} (layer {layer_names(technique)[0].rpartition('.')[0]}), "
            f"{where}",
        )
        return {"FINISHED"}


classes = (SSS_LAB_OT_apply,)
