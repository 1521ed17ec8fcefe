"""Property groups: SSS Lab's settings, stored on the scene (``scene.sss_lab``)."""

from __future__ import annotations

import inspect

import bpy

from ..core.apply import ALBEDO_MODES
from ..core.kernels import KERNEL_TYPES
from ..core.mapping import BURLEY_DEFAULTS, SSSS_DEFAULTS, STA_DEFAULTS
from ..core.techniques import TECHNIQUES, get_technique
from .bake_settings import SSSLabBakeSettings

# Blender keeps a reference to the items of a dynamic enum; a static list avoids that trap.
_TECHNIQUE_ITEMS = [(name, label, desc) for name, (_, _, label, desc) in TECHNIQUES.items()]
_ALBEDO_ITEMS = [
    ("post", "Post-scatter", "Albedo applied after scattering: the texture detail is blurred away"),
    ("pre-post", "Pre- and post-scatter", "Square root of the albedo before and after: keeps half of the detail"),
]
assert [i[0] for i in _ALBEDO_ITEMS] == list(ALBEDO_MODES)
#: Burley's random rotation: the technique function's own default (not in core.mapping's table).
_BURLEY_ROTATION = inspect.signature(get_technique("burley")).parameters["random_rotation"].default
_TAPS_ITEMS = [
    ("11", "11", "11 taps per direction (Unreal's low quality)"),
    ("17", "17", "17 taps per direction (Unreal's medium quality)"),
    ("25", "25", "25 taps per direction (Unreal's high quality)"),
]
_KERNEL_ITEMS = [
    ("preintegrated", "Pre-integrated", "Kernel integrated from the material's diffusion profile"),
    ("artist", "Artist", "Jimenez et al.'s artist-friendly kernel (strength and falloff per channel)"),
]
assert sorted(i[0] for i in _KERNEL_ITEMS) == sorted(KERNEL_TYPES)


class SSSLabSettings(bpy.types.PropertyGroup):
    technique: bpy.props.EnumProperty(
        name="Technique",
        description="Real-time subsurface scattering approximation to use",
        items=_TECHNIQUE_ITEMS,
        default="burley",
    )
    bake: bpy.props.PointerProperty(type=SSSLabBakeSettings, name="Thickness Bake")

    # -- technique parameters (defaults: core/mapping.py) ------------------------------------
    sta_distortion: bpy.props.FloatProperty(
        name="Distortion",
        description="How far the surface normal bends the light direction (L + distortion N)",
        default=STA_DEFAULTS["distortion"],
        min=0.0,
        soft_max=1.0,
    )
    sta_power: bpy.props.FloatProperty(
        name="Power",
        description="Exponent of the view-dependent back-light term (higher: tighter)",
        default=STA_DEFAULTS["power"],
        min=0.0,
        soft_max=16.0,
    )
    sta_scale: bpy.props.FloatProperty(
        name="Scale",
        description="Brightness of the translucency",
        default=STA_DEFAULTS["scale"],
        min=0.0,
        soft_max=20.0,
    )
    sta_ambient: bpy.props.FloatProperty(
        name="Ambient",
        description="Translucency that does not depend on the view direction",
        default=STA_DEFAULTS["ambient"],
        min=0.0,
        soft_max=1.0,
    )
    sta_falloff: bpy.props.EnumProperty(
        name="Falloff",
        description="How the thickness map scales the translucency",
        items=(
            ("map", "Map", "The paper's: the translucency map itself, the same for R, G and B"),
            (
                "burley",
                "Burley Transmission",
                "Per-channel Burley transmittance through the slab thickness the baked map stands for"
                " (uses the bake distance; red passes thick parts best)",
            ),
        ),
        default="map",
    )
    ssss_taps: bpy.props.EnumProperty(
        name="Taps",
        description="Samples of each of the two 1-D convolutions",
        items=_TAPS_ITEMS,
        default=str(SSSS_DEFAULTS["n_taps"]),
    )
    ssss_kernel: bpy.props.EnumProperty(
        name="Kernel",
        description="How the separable kernel is built",
        items=_KERNEL_ITEMS,
        default=SSSS_DEFAULTS["kernel_type"],
    )
    burley_samples: bpy.props.IntProperty(
        name="Samples",
        description="Samples per pixel of the golden-angle spiral",
        default=BURLEY_DEFAULTS["n_samples"],
        min=1,
        max=1024,
        soft_max=128,
    )
    burley_random_rotation: bpy.props.BoolProperty(
        name="Random Rotation",
        description="Rotate the spiral per pixel: noise instead of banding",
        default=bool(BURLEY_DEFAULTS.get("random_rotation", _BURLEY_ROTATION)),
    )
    albedo_mode: bpy.props.EnumProperty(
        name="Albedo",
        description="When the albedo (Diffuse Color) is applied (SSSS and Burley)",
        items=_ALBEDO_ITEMS,
        default=ALBEDO_MODES[0],
    )

    # -- render passes and apply -------------------------------------------------------------
    render_all: bpy.props.BoolProperty(
        name="All Techniques",
        description="Render the passes of every technique (else those of the chosen technique)",
        default=False,
    )
    output_dir: bpy.props.StringProperty(
        name="Output",
        description="Folder for the passes (passes_####.exr and .json); // = beside the .blend file",
        default="//sss_lab/",
        subtype="DIR_PATH",
    )
    render_samples: bpy.props.IntProperty(
        name="Samples",
        description="Cycles samples for the passes (adaptive sampling is off); 0 = the scene's",
        default=64,
        min=0,
        soft_max=1024,
    )
    passes_file: bpy.props.StringProperty(
        name="Passes",
        description="Passes EXR that Apply reads (Render Passes sets it to the file it wrote)",
        default="",
        subtype="FILE_PATH",
    )

    def technique_options(self, technique: str) -> dict:
        """The panel's parameters of ``technique`` as keyword options of ``core.apply``."""
        if technique == "sta":
            return {
                "distortion": self.sta_distortion,
                "power": self.sta_power,
                "scale": self.sta_scale,
                "ambient": self.sta_ambient,
                "falloff": self.sta_falloff,
            }
        if technique == "ssss":
            return {"n_taps": int(self.ssss_taps), "kernel_type": self.ssss_kernel}
        if technique in ("burley", "combined"):
            # The combined technique's diffusion is Burley's: it shares the Burley rows of the panel.
            return {"n_samples": self.burley_samples, "random_rotation": self.burley_random_rotation}
        raise ValueError(f"unknown technique {technique!r}; expected one of: {', '.join(TECHNIQUES)}")

    def render_techniques(self) -> list[str]:
        return list(TECHNIQUES) if self.render_all else [self.technique]


classes = (SSSLabBakeSettings, SSSLabSettings)


def attach():
    bpy.types.Scene.sss_lab = bpy.props.PointerProperty(type=SSSLabSettings)


def detach():
    if hasattr(bpy.types.Scene, "sss_lab"):
        del bpy.types.Scene.sss_lab
