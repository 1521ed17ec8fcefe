"""Property groups: SSS Lab's settings, stored on the scene (``scene.sss_lab``)."""

from __future__ import annotations

import bpy

from ..core.techniques import TECHNIQUES
from .bake_settings import SSSLabBakeSettings

# Blender keeps a reference to the items of a dynamic enum; a static list avoids that trap.
_TECHNIQUE_ITEMS = [(name, label, desc) for name, (_, _, label, desc) in TECHNIQUES.items()]


class SSSLabSettings(bpy.types.PropertyGroup):
    technique: bpy.props.EnumProperty(
        name="Technique",
        description="Real-time subsurface scattering approximation to use",
        items=_TECHNIQUE_ITEMS,
        default="burley",
    )
    bake: bpy.props.PointerProperty(type=SSSLabBakeSettings, name="Thickness Bake")


classes = (SSSLabBakeSettings, SSSLabSettings)


def attach():
    bpy.types.Scene.sss_lab = bpy.props.PointerProperty(type=SSSLabSettings)


def detach():
    if hasattr(bpy.types.Scene, "sss_lab"):
        del bpy.types.Scene.sss_lab
