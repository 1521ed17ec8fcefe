"""Which materials of a scene scatter, with which method and radius."""

from __future__ import annotations

from ..core.base.progress import printable
from .describe import read_material, scene_materials, sss_materials


def scan_report(scene) -> list[str]:
    """Per subsurface material of ``scene``: its method, weight and radius, then each subsurface
    input as typed in or linked and how it is read, and what could not be followed; or one line
    saying there is none."""
    materials = sss_materials(scene)
    if not materials:
        return [f"Scene {scene.name!r}: no material with subsurface scattering (Subsurface Weight > 0)"]
    by_name = {m.name: m for m in scene_materials(scene)}
    lines = [f"Scene {scene.name!r}: {len(materials)} subsurface material(s)"]
    for m in materials:
        radius = ", ".join(f"{r:.4g}" for r in m.radius)
        weight = f"{m.subsurface_weight:.3g}"
        lines.append(f"  {printable(m.name)}: method {m.method}, weight {weight}, radius x scale ({radius})")
        reading = read_material(by_name[m.name], m.index)
        lines += [f"    {line}" for line in reading.inputs]
        lines += [f"    note: {note}" for note in reading.notes]
    return lines


def recommend(
    scene, *, resolution=None, samples: int = 16, max_error: float | None = None, rungs: bool = False, log=None
) -> list[str]:
    """``recommendation``'s lines."""
    return recommendation(scene, resolution=resolution, samples=samples, max_error=max_error, rungs=rungs, log=log)[0]


def recommendation(
    scene, *, resolution=None, samples: int = 16, max_error: float | None = None, rungs: bool = False, log=None
):
    """Per subsurface material of ``scene``, the technique (with ``rungs``, and the rung of its
    quality ladder) ``apply --methods auto`` would choose, and why (``core.pipeline.auto``): renders the passes of the
    scene's view once, small and at few samples (``resolution`` "WxH", default the scene's scaled
    so that its long side is at most 160 px), into a temporary folder; the scene is left as it
    was. Returns (the lines to print, the ``AutoPlan`` or None without a subsurface material)."""
    from ..core.base import files
    from ..core.pipeline import auto, sequence
    from ..core.scene import exr
    from .render_passes import render_passes

    if sss_materials(scene) == []:
        return scan_report(scene), None
    if resolution is None:
        r = scene.render
        w, h = r.resolution_x * r.resolution_percentage // 100, r.resolution_y * r.resolution_percentage // 100
        k = min(1.0, 160.0 / max(w, h, 1))
        resolution = (max(int(w * k), 8), max(int(h * k), 8))
    limit = auto.DEFAULT_MAX_ERROR if max_error is None else max_error
    with files.temporary_folder("sss_lab_scan_") as folder:
        written = render_passes(scene, folder, samples=samples, resolution=resolution, seed=0, log=log)
        path = next(p for p in written if p.endswith(".exr"))
        plan = auto.choose(exr.read_passes(path), sequence.load_scene(path), max_error=limit, rungs=rungs)
    w, h = plan.shape[1], plan.shape[0]
    lines = [
        f"Recommendations (passes rendered at {w}x{h}, {samples} samples; what `apply --methods auto` chooses at"
        " that size):"
    ]
    lines += plan.explain().splitlines()[1:]
    return lines, plan
