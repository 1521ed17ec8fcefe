"""Which materials of a scene scatter, with which method and radius."""

from __future__ import annotations

from .describe import sss_materials


def scan_report(scene) -> list[str]:
    """One line per subsurface material of ``scene``, or one line saying there is none."""
    materials = sss_materials(scene)
    if not materials:
        return [f"Scene {scene.name!r}: no material with subsurface scattering (Subsurface Weight > 0)"]
    lines = [f"Scene {scene.name!r}: {len(materials)} subsurface material(s)"]
    for m in materials:
        radius = ", ".join(f"{r:.4g}" for r in m.radius)
        lines.append(f"  {m.name}: method {m.method}, weight {m.subsurface_weight:.3g}, radius x scale ({radius})")
    return lines
