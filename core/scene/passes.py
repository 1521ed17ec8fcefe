"""One table of render-pass facts, read by every layer that names a pass.

For each pass a technique may read (and the others a Blender file may hold): its name as
Blender 5.x writes it, the view-layer flag that switches it on (Cycles), the channel letters
Blender 5.2 writes, its Blender 4.x short name (``RE_PASSNAME_*`` in Blender's
``DNA_scene_types.h`` and the Cycles pass names of ``blender/sync.cpp``; AOVs, light groups and
Cryptomatte layers keep their own names), and where a user switches it on. The render
(``blender/render_passes.py``), the compositor set-up, the EXR reader (``core/scene/exr.py``) and the
techniques' ``passes`` (``core/techniques/spec.py``) all read this table.

``THICKNESS`` is not a pass but the scene's thickness shader AOV
(``SceneDescription.thickness_aov``, "Thickness" by default): a technique that lists it reads
the AOV under the scene's name for it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PassInfo:
    """The facts about one render pass."""

    #: The name Blender 5.x writes (``ViewLayer.<name>.<channel>``).
    name: str
    #: The view-layer property that switches it on: ``use_pass_*`` on the view layer, or
    #: ``cycles.use_pass_*`` on its Cycles settings; None for an AOV.
    flag: str | None
    #: Channel letters Blender 5.2 writes for it.
    channels: str
    #: The name Blender 4.x writes, or None when it is the same.
    short_name: str | None = None
    #: Where to switch it on in Blender 5.2 (for error messages), or None for the generic advice.
    hint: str | None = None


_PANEL = "View Layer Properties > Passes"
#: What an index pass needs besides its flag.
_EXTRA = {
    "Object Index": ", and give each object a Pass Index in Object Properties > Relations",
    "Material Index": ", and give each material a Pass Index in Material Properties > Settings",
}

# (name, flag, channels, 4.x short name, menu path under View Layer Properties > Passes)
_ROWS = (
    ("Combined", "use_pass_combined", "RGBA", None, "Data > Combined"),
    ("Depth", "use_pass_z", "Z", None, "Data > Depth"),
    ("Mist", "use_pass_mist", "Z", None, "Data > Mist"),
    ("Position", "use_pass_position", "XYZ", None, "Data > Position"),
    ("Normal", "use_pass_normal", "XYZ", None, "Data > Normal"),
    ("Vector", "use_pass_vector", "XYZW", None, "Data > Vector"),
    ("UV", "use_pass_uv", "UVA", None, "Data > UV"),
    ("Object Index", "use_pass_object_index", "X", "IndexOB", "Data > Indexes > Object Index"),
    ("Material Index", "use_pass_material_index", "X", "IndexMA", "Data > Indexes > Material Index"),
    ("Diffuse Direct", "use_pass_diffuse_direct", "RGB", "DiffDir", "Light > Diffuse > Direct"),
    ("Diffuse Indirect", "use_pass_diffuse_indirect", "RGB", "DiffInd", "Light > Diffuse > Indirect"),
    ("Diffuse Color", "use_pass_diffuse_color", "RGB", "DiffCol", "Light > Diffuse > Color"),
    ("Glossy Direct", "use_pass_glossy_direct", "RGB", "GlossDir", "Light > Glossy > Direct"),
    ("Glossy Indirect", "use_pass_glossy_indirect", "RGB", "GlossInd", "Light > Glossy > Indirect"),
    ("Glossy Color", "use_pass_glossy_color", "RGB", "GlossCol", "Light > Glossy > Color"),
    ("Transmission Direct", "use_pass_transmission_direct", "RGB", "TransDir", "Light > Transmission > Direct"),
    ("Transmission Indirect", "use_pass_transmission_indirect", "RGB", "TransInd", "Light > Transmission > Indirect"),
    ("Transmission Color", "use_pass_transmission_color", "RGB", "TransCol", "Light > Transmission > Color"),
    ("Subsurface Direct", "use_pass_subsurface_direct", "RGB", "SubsurfaceDir", "Light > Subsurface > Direct"),
    ("Subsurface Indirect", "use_pass_subsurface_indirect", "RGB", "SubsurfaceInd", "Light > Subsurface > Indirect"),
    ("Subsurface Color", "use_pass_subsurface_color", "RGB", "SubsurfaceCol", "Light > Subsurface > Color"),
    ("Volume Direct", "cycles.use_pass_volume_direct", "RGB", "VolumeDir", "Light > Volume > Direct"),
    ("Volume Indirect", "cycles.use_pass_volume_indirect", "RGB", "VolumeInd", "Light > Volume > Indirect"),
    ("Emission", "use_pass_emit", "RGB", "Emit", "Light > Other > Emission"),
    ("Environment", "use_pass_environment", "RGB", "Env", "Light > Other > Environment"),
    ("Ambient Occlusion", "use_pass_ambient_occlusion", "RGB", "AO", "Light > Other > Ambient Occlusion"),
    ("Transparent", None, "RGBA", "Transp", None),
)

#: Pass name -> its facts.
PASSES: dict[str, PassInfo] = {
    name: PassInfo(
        name=name,
        flag=flag,
        channels=channels,
        short_name=short,
        hint=f"{_PANEL} > {menu} (view_layer.{flag}){_EXTRA.get(name, '')}" if menu else None,
    )
    for name, flag, channels, short, menu in _ROWS
}

#: Stands for the scene's thickness AOV in a technique's ``passes``.
THICKNESS = "Thickness"

#: Blender 4.x short name -> Blender 5.x name.
SHORT_NAMES: dict[str, str] = {p.short_name: p.name for p in PASSES.values() if p.short_name}


def pass_hint(name: str) -> str:
    """How to enable pass ``name`` in Blender; AOVs and unknown names get the Shader AOV advice."""
    info = PASSES.get(name)
    if info is not None and info.hint is not None:
        return info.hint
    return (
        f"{_PANEL} > Shader AOV > + (name {name!r}), fed in the materials by an AOV Output node "
        f"named {name!r} (view_layer.aovs.add())"
    )


def view_layer_flag(name: str) -> str:
    """The view-layer flag of pass ``name``; ValueError for an AOV or an unknown pass."""
    info = PASSES.get(name)
    if info is None or info.flag is None:
        raise ValueError(f"{name!r} is not a render pass with a view-layer flag; known: {', '.join(PASSES)}")
    return info.flag


@dataclass(frozen=True)
class InputAOV:
    """A shader AOV that carries one subsurface input per pixel, rendered only for the
    materials whose input is linked to something the scene reader cannot read as a constant (a
    texture, an attribute, a Math node, a driver through a node group)."""

    #: The ``MaterialSSS`` field it measures.
    key: str
    #: The AOV's name on the view layer and in the passes file.
    name: str
    #: Blender's AOV type: "COLOR" for an RGB input, "VALUE" for a number.
    kind: str
    #: The AOV Output node's input that takes it.
    socket: str


#: The subsurface inputs read per pixel when linked, by ``MaterialSSS`` field.
INPUT_AOVS: dict[str, InputAOV] = {
    a.key: a
    for a in (
        InputAOV("base_color", "SSSLab Base Color", "COLOR", "Color"),
        InputAOV("subsurface_radius", "SSSLab Radius", "COLOR", "Color"),
        InputAOV("subsurface_scale", "SSSLab Scale", "VALUE", "Value"),
        InputAOV("subsurface_weight", "SSSLab Weight", "VALUE", "Value"),
    )
}
