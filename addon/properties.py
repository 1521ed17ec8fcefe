"""Property groups: SSS Lab's settings, stored on the scene (``scene.sss_lab``)."""

from __future__ import annotations

import bpy

from ..core.pipeline.apply import ALBEDO_MODES
from ..core.techniques.registry import DEFAULT_TECHNIQUE, TECHNIQUES
from ..core.techniques.spec import Param, Technique
from .bake_settings import SSSLabBakeSettings

# Blender keeps a reference to the items of a dynamic enum; a static list avoids that trap.
_TECHNIQUE_ITEMS = [(name, t.label, t.description) for name, t in TECHNIQUES.items()]
_ALBEDO_ITEMS = [
    ("post", "Post-scatter", "Albedo applied after scattering: the texture detail is blurred away"),
    ("pre-post", "Pre- and post-scatter", "Square root of the albedo before and after: keeps half of the detail"),
]
assert [i[0] for i in _ALBEDO_ITEMS] == list(ALBEDO_MODES)


def _property(p: Param):
    """The Blender property of one parameter spec (name, description, default, range, choices)."""
    common = {"name": p.label, "description": p.description}
    if p.choices:
        # Enum identifiers are strings: the value's text, turned back by ``technique_options``.
        items = [(str(value), label, description) for value, label, description in p.choices]
        return bpy.props.EnumProperty(items=items, default=str(p.default), **common)
    if p.type is bool:
        return bpy.props.BoolProperty(default=bool(p.default), **common)
    if p.type is str:
        return bpy.props.StringProperty(default=str(p.default), **common)
    limits = {key: getattr(p, key) for key in ("min", "max", "soft_max") if getattr(p, key) is not None}
    if p.type is int:
        return bpy.props.IntProperty(default=int(p.default), **common, **{k: int(v) for k, v in limits.items()})
    return bpy.props.FloatProperty(default=float(p.default), **common, **limits)


def _group(spec: Technique) -> type:
    """A PropertyGroup with one property per parameter of ``spec`` (``scene.sss_lab.<name>``)."""
    return type(
        f"SSSLab_{spec.name}_settings",
        (bpy.types.PropertyGroup,),
        {
            "__annotations__": {p.name: _property(p) for p in spec.params},
            "__doc__": f"The {spec.label} technique's parameters ({spec.citation})",
        },
    )


#: Technique name -> its PropertyGroup, made from its spec.
TECHNIQUE_GROUPS: dict[str, type] = {name: _group(spec) for name, spec in TECHNIQUES.items()}


def technique_values(spec: Technique, group) -> dict:
    """The values of ``group`` (a technique's PropertyGroup) as keyword options of its function,
    each checked against its parameter spec."""
    values = {}
    for p in spec.params:
        value = getattr(group, p.name)
        if p.choices:
            value = next(v for v in p.values if str(v) == value)
        values[p.name] = value
    return spec.check_params(values)


class SSSLabSettings(bpy.types.PropertyGroup):
    technique: bpy.props.EnumProperty(
        name="Technique",
        description="Real-time subsurface scattering approximation to use",
        items=_TECHNIQUE_ITEMS,
        default=DEFAULT_TECHNIQUE,
    )
    bake: bpy.props.PointerProperty(type=SSSLabBakeSettings, name="Thickness Bake")

    # -- technique parameters: one group per technique (``TECHNIQUE_GROUPS``), attached below
    albedo_mode: bpy.props.EnumProperty(
        name="Albedo",
        description="When the albedo (Diffuse Color) is applied (SSSS and Burley)",
        items=_ALBEDO_ITEMS,
        default=ALBEDO_MODES[0],
    )

    # -- compositor --------------------------------------------------------------------------
    compositor_route: bpy.props.EnumProperty(
        name="Burley Route",
        description="How Set Up Compositor's Burley groups scatter",
        items=[
            (
                "convolve",
                "Convolve (exact)",
                "The exact profile in Convolve nodes: an FFT on the CPU, even with the GPU compositor",
            ),
            (
                "gaussians",
                "Gaussians (GPU)",
                "The profile as six Gaussians in Blur nodes: runs on the GPU compositor; within about 1 % of"
                " the exact profile's scattering (docs/compositor.md)",
            ),
        ],
        default="convolve",
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
        """The panel's parameters of ``technique`` as keyword options of ``core.pipeline.apply``."""
        spec = TECHNIQUES.get_spec(technique)
        return technique_values(spec, getattr(self, spec.name))

    def render_techniques(self) -> list[str]:
        return list(TECHNIQUES) if self.render_all else [self.technique]


_TAKEN = set(SSSLabSettings.__annotations__)
for _name, _cls in TECHNIQUE_GROUPS.items():
    # A technique's group sits beside the other settings: its name must not be one of theirs.
    assert _name not in _TAKEN, f"technique {_name!r} clashes with a setting of SSSLabSettings"
    SSSLabSettings.__annotations__[_name] = bpy.props.PointerProperty(type=_cls, name=TECHNIQUES[_name].label)

classes = (SSSLabBakeSettings, *TECHNIQUE_GROUPS.values(), SSSLabSettings)


def attach():
    bpy.types.Scene.sss_lab = bpy.props.PointerProperty(type=SSSLabSettings)


def detach():
    if hasattr(bpy.types.Scene, "sss_lab"):
        del bpy.types.Scene.sss_lab
