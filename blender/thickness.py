"""Thickness maps as the bake left them: their stored settings and where a material reads them.

``thickness_setup`` finds, for STA, which subsurface materials feed the thickness AOV and with
which convention, reading the settings ``blender.bake`` stores with a map (on the mesh per
attribute, or on the image: ``stored.thickness_metadata``).
"""

from __future__ import annotations

from .describe import scene_materials
from .stored import thickness_metadata


def thickness_aov_name(scene) -> str:
    """The thickness AOV: the panel's bake setting, or "Thickness" without the add-on."""
    bake = getattr(getattr(scene, "sss_lab", None), "bake", None)
    return (getattr(bake, "aov_name", "") or "Thickness").strip() or "Thickness"


def thickness_source(material, aov_name: str):
    """The node that feeds ``material``'s thickness AOV, or None when nothing does."""
    if material.node_tree is None:
        return None
    for node in material.node_tree.nodes:
        if node.bl_idname == "ShaderNodeOutputAOV" and node.aov_name == aov_name and not node.mute:
            for socket in (node.inputs.get("Value"), node.inputs.get("Color")):
                if socket is not None and socket.is_linked:
                    return socket.links[0].from_node
    return None


def source_convention(scene, material, source) -> str | None:
    """The convention stored with the baked map ``source`` reads, if SSS Lab baked it."""
    if source.bl_idname == "ShaderNodeTexImage" and source.image is not None:
        meta = thickness_metadata(source.image)
        return meta.get("convention") if meta else None
    if source.bl_idname == "ShaderNodeAttribute":
        for obj in scene.objects:
            if obj.type == "MESH" and material.name in {s.material.name for s in obj.material_slots if s.material}:
                meta = thickness_metadata(obj.data, source.attribute_name)
                if meta:
                    return meta.get("convention")
    return None


def thickness_setup(scene, materials: list, aov_name: str) -> tuple[str, list[str]]:
    """(convention, names of subsurface materials without a thickness map) for STA.

    ValueError when no subsurface material feeds the thickness AOV, or the maps disagree on
    their convention.
    """
    by_name = {m.name: m for m in scene_materials(scene)}
    conventions: dict[str, list[str]] = {}
    missing = []
    for info in materials:
        mat = by_name[info.name]
        source = thickness_source(mat, aov_name)
        if source is None:
            missing.append(mat.name)
            continue
        conv = source_convention(scene, mat, source) or "translucency"
        conventions.setdefault(conv, []).append(mat.name)
    if len(missing) == len(materials):
        names = ", ".join(repr(n) for n in missing)
        raise ValueError(
            f"STA needs a baked thickness map, but no subsurface material ({names}) feeds the shader AOV "
            f"{aov_name!r}: bake thickness first (Render tab > SSS Lab > Thickness Bake > Bake Thickness, "
            "or python -m sss_lab bake-thickness), or render without STA (--methods ssss,burley)"
        )
    if len(conventions) > 1:
        detail = "; ".join(f"{c}: {', '.join(names)}" for c, names in conventions.items())
        raise ValueError(
            f"the thickness maps use different conventions ({detail}); STA reads one convention per scene: "
            "bake them again with the same convention"
        )
    return next(iter(conventions)), missing
