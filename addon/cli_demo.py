"""``python -m sss_lab demo``: the main job on the bundled sample scene.

Builds the default sample scene from ``sample_blends/build_scenes.py`` and runs the comparison
on it (``blender/compare.py``): the Cycles random-walk reference, the passes the techniques
need, every technique at several qualities, and the report folder with metrics.json,
report.md, report.html, the image grid and the error-against-time plot.
"""

from __future__ import annotations

import os
import time


def add_parser(subparsers):
    p = subparsers.add_parser(
        "demo", help="build the sample scene and compare every technique with Cycles random walk (needs bpy)"
    )
    p.add_argument("--out", default="out", help="output folder (default: out)")
    # Not --scene: that names a scene of a .blend file in every command.
    p.add_argument("--sample", default=None, metavar="NAME", help="sample scene to build (default: the demo scene)")
    p.add_argument("--reference-samples", type=int, default=512, help="Cycles samples of the reference (default 512)")
    from .cli_options import deprecated_alias

    p.add_argument(
        "--pass-samples",
        "--samples",
        type=int,
        default=64,
        action=deprecated_alias("--samples"),
        help="Cycles samples of the passes (default 64)",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    from .cli import CommandError, require_bpy

    require_bpy()
    from ..blender.samples import load_sample_scenes

    for name in ("pass_samples", "reference_samples"):
        if getattr(args, name) < 1:
            raise CommandError(f"--{name.replace('_', '-')}: expected an integer >= 1, got {getattr(args, name)}")
    scenes = load_sample_scenes()
    name = args.sample or scenes.DEFAULT_SCENE
    if name not in scenes.SCENES:
        raise CommandError(f"unknown sample scene {name!r}; expected one of: {', '.join(scenes.SCENES)}")
    if os.path.exists(args.out) and not os.path.isdir(args.out):
        raise CommandError(f"--out {args.out!r} is a file; expected a folder for the demo's scene and report")
    out = os.path.abspath(os.path.join(args.out, name))
    os.makedirs(out, exist_ok=True)
    start = time.perf_counter()
    blend = scenes.build(name, os.path.join(out, f"{name}.blend"))
    from ..core.base.progress import saved_line

    print(saved_line(blend))

    import bpy

    from ..blender import compat
    from ..blender.compare import CompareSettings, compare
    from ..core.study.report_schema import Report

    # Every subsurface method of this Blender gets its mapping calibrated (one more cached
    # reference each).
    settings = CompareSettings(
        reference_samples=args.reference_samples,
        pass_samples=args.pass_samples,
        calibrate_methods=compat.subsurface_methods(),
    )
    try:
        data = compare(bpy.context.scene, out, settings)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    print(f"Demo done in {time.perf_counter() - start:.0f} s. On {name}, against Cycles random walk")
    print("(relative RMSE over the subsurface pixels; lower is better):")
    report = Report.from_dict(data)
    noise = report.noise_floor["rel_rmse"]
    shown = report.extra.get("summary", {}).get("columns", [])
    front = set(report.pareto)
    for e in report.entries:
        if e.name in shown or (e.kind == "technique" and e.name in front) or e.kind == "eevee":
            apply_s = e.time_s.get("apply")
            cost = f", apply {apply_s * 1e3:.0f} ms" if apply_s is not None else ""
            mark = " (on the error/time Pareto front)" if e.name in front else ""
            print(f"  {e.name:22s} {e.metrics['rel_rmse']:.3f}{cost}{mark}")
    print(f"  noise floor of the reference: {noise:.3f}")
    eevee = data.get("eevee") or {}
    if eevee.get("error"):
        print(f"  EEVEE left out: {eevee['error']}")
    print(f"Report: {os.path.join(out, 'report.html')} (and report.md, metrics.json)")
    if not report.complete:
        print("The report is incomplete: " + "; ".join(report.notes))
        return 1
    return 0
