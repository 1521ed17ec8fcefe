"""``bpy.ops.sss_lab.export_profiles``: each material's profile as Unity HDRP, Unreal and EEVEE values,
and the baked thickness images in the bakers' convention (``blender.export_profiles``), into a
folder chosen in the file browser. Writes files only: the scene is not changed (no undo step)."""

from __future__ import annotations

import os

import bpy

from ..blender.export_profiles import write_export
from ..core.base.errors import InputError
from ..core.pipeline.fit_params import FIT_PARAMETERS


class SSS_LAB_OT_export_profiles(bpy.types.Operator):
    """Export each material's profile for Unity HDRP, Unreal and EEVEE, with the baked thickness maps"""

    bl_idname = "sss_lab.export_profiles"
    bl_label = "Export Profiles"
    bl_options = {"REGISTER"}

    directory: bpy.props.StringProperty(
        name="Folder",
        description="Folder for profiles.json, profiles.md and the thickness maps",
        subtype="DIR_PATH",
        default="//sss_lab_profiles/",
        options={"PATH_SUPPORTS_BLEND_RELATIVE"},
    )
    technique: bpy.props.EnumProperty(
        name="Fit Of",
        description="Whose fit (stored by Fit to Cycles) sets the profile's width and gain",
        items=[(t, t.upper() if len(t) <= 4 else t.title(), f"the fit of {t}") for t in FIT_PARAMETERS if t != "sta"],
        default="burley",
    )
    albedo_mode: bpy.props.EnumProperty(
        name="Albedo",
        description="How the engine applies the albedo (HDRP's Texturing Mode)",
        items=[
            ("post", "Post-Scatter", "the albedo after the blur"),
            ("pre-post", "Pre- and Post-Scatter", "the square root of the albedo before and after"),
        ],
        default="post",
    )
    overwrite: bpy.props.BoolProperty(name="Overwrite", description="Replace files that already exist")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        folder = bpy.path.abspath(self.directory)
        # An unsaved file has no folder for "//": abspath would quietly use the working directory.
        if not folder or (self.directory.startswith("//") and not bpy.data.filepath):
            self.report({"ERROR"}, "Save the .blend file first, or choose an absolute folder")
            return {"CANCELLED"}
        notes: list[str] = []
        try:
            data, written = write_export(
                context.scene,
                folder,
                overwrite=self.overwrite,
                technique=self.technique,
                albedo_mode=self.albedo_mode,
                protect=(bpy.data.filepath,) if bpy.data.filepath else (),
                log=notes.append,
            )
        except (InputError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for line in notes:
            self.report({"WARNING"}, line)
        if not written:
            self.report({"WARNING"}, "No material with subsurface scattering: nothing exported")
            return {"CANCELLED"}
        self.report(
            {"INFO"},
            f"Exported {len(data['materials'])} material(s) to {os.path.join(folder, 'profiles.md')}"
            f" ({len(written)} files)",
        )
        return {"FINISHED"}


classes = (SSS_LAB_OT_export_profiles,)
