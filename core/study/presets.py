"""Material presets: Principled BSDF subsurface values for a few materials, with their source.

Each preset gives Base Color, Subsurface Radius and Subsurface Scale (Subsurface Weight 1).
Skin and marble are measurements: Jensen, Marschner, Levoy & Hanrahan, "A Practical Model for
Subsurface Light Transport", SIGGRAPH 2001, Figure 5 (the table of measured parameters, per
channel R, G, B): the diffuse reflectance R_d becomes the Base Color and the diffuse mean free
path l_d = 1 / sigma_tr (in mm) becomes Radius x Scale. Reading l_d as the Principled BSDF's
radius ("the average distance light scatters below the surface") is the usual way these
measurements are entered into a renderer; Cycles' subsurface methods then interpret the radius
each in their own way (docs/references.md §2; ``core/pipeline/mapping.py``).

Wax and jade have no measurement in that paper: their values are an artistic choice (a look,
not a measurement), and their ``source`` says so.

Lengths are stored in millimetres; ``principled_values`` converts them to scene units
(1 scene unit = ``unit_scale_m`` metres, Blender's Unit Scale; 1 by default).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

_JENSEN_2001 = (
    "Jensen et al. 2001, 'A Practical Model for Subsurface Light Transport' (SIGGRAPH), Figure 5: "
    "measured diffuse reflectance R_d (Base Color) and diffuse mean free path l_d (Radius x Scale)"
)


@dataclass(frozen=True)
class Preset:
    """Subsurface values of one material. ``mean_free_path_mm`` is per channel (R, G, B)."""

    name: str
    label: str
    base_color: tuple[float, float, float]
    mean_free_path_mm: tuple[float, float, float]
    measured: bool
    source: str

    def principled_values(self, unit_scale_m: float = 1.0) -> dict[str, Any]:
        """Base Color (RGBA), Subsurface Weight, Radius (largest channel 1) and Scale (scene units)."""
        if not (isinstance(unit_scale_m, (int, float)) and math.isfinite(unit_scale_m) and unit_scale_m > 0):
            raise ValueError(
                f"unit_scale_m: expected a finite number > 0 (metres per scene unit), got {unit_scale_m!r}"
            )
        longest = max(self.mean_free_path_mm)
        return {
            "Base Color": (*self.base_color, 1.0),
            "Subsurface Weight": 1.0,
            "Subsurface Radius": tuple(v / longest for v in self.mean_free_path_mm),
            "Subsurface Scale": longest * 1e-3 / unit_scale_m,
        }


PRESETS: dict[str, Preset] = {
    p.name: p
    for p in (
        Preset(
            name="skin",
            label="Skin",
            # Jensen et al. 2001, Skin1.
            base_color=(0.436, 0.227, 0.131),
            mean_free_path_mm=(3.67, 1.37, 0.68),
            measured=True,
            source=_JENSEN_2001 + " (Skin1)",
        ),
        Preset(
            name="marble",
            label="Marble",
            base_color=(0.830, 0.791, 0.753),
            mean_free_path_mm=(8.51, 5.57, 3.95),
            measured=True,
            source=_JENSEN_2001 + " (Marble)",
        ),
        Preset(
            name="wax",
            label="Wax",
            base_color=(0.90, 0.80, 0.60),
            mean_free_path_mm=(8.0, 6.0, 4.0),
            measured=False,
            source="artistic choice (no measurement): a warm candle wax that glows deeply in red",
        ),
        Preset(
            name="jade",
            label="Jade",
            base_color=(0.35, 0.62, 0.42),
            mean_free_path_mm=(2.0, 4.0, 2.5),
            measured=False,
            source="artistic choice (no measurement): green scatters furthest, giving jade's green glow",
        ),
    )
}


def get_preset(name: str) -> Preset:
    """The preset called ``name``; ValueError listing the known ones."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; expected one of: {', '.join(PRESETS)}") from None
