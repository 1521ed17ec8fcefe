"""Set a material's Principled BSDF to a preset of ``core/study/presets.py``."""

from __future__ import annotations

from ..core.study.presets import get_preset
from .describe import principled_node


def apply_preset(material, name: str, unit_scale_m: float = 1.0) -> dict:
    """Set the subsurface inputs of ``material``'s Principled BSDF to preset ``name``.

    Lengths become scene units with ``unit_scale_m`` metres per unit (the scene's Unit Scale).
    Returns the values set. ValueError when the material has no Principled BSDF, or an input is
    driven by a link (the preset would not show).
    """
    preset = get_preset(name)
    node = principled_node(material)
    if node is None:
        what = "no material" if material is None else f"material {material.name!r} has no Principled BSDF"
        raise ValueError(f"cannot apply the {preset.label} preset: {what}")
    values = preset.principled_values(unit_scale_m)
    linked = [n for n in values if node.inputs[n].is_linked]
    if linked:
        raise ValueError(
            f"material {material.name!r}: {', '.join(linked)} driven by a link; disconnect it to use the "
            f"{preset.label} preset"
        )
    for socket, value in values.items():
        node.inputs[socket].default_value = value
    return values
