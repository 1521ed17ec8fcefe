"""``python -m sss_lab scan SCENE.blend [--recommend]``: list the scene's subsurface materials, and with
``--recommend`` the technique and quality ``apply --methods auto`` would choose for each (``blender/scan.py``)."""

from __future__ import annotations

import os


def add_parser(subparsers):
    from .cli_options import add_blend, add_resolution, add_samples, add_scene

    p = subparsers.add_parser("scan", help="list the subsurface materials of a .blend scene (needs bpy)")
    add_blend(p)
    add_scene(p)
    p.add_argument(
        "--recommend",
        action="store_true",
        help="per material, the technique and its quality (rung) `apply --methods auto` would choose and why (renders"
        " small passes once)",
    )
    add_resolution(p, help="with --recommend: WIDTHxHEIGHT of that render (default: long side 160 px)")
    add_samples(p, default=16, help="with --recommend: samples of that render (default: 16)")
    p.add_argument("--max-error", type=float, help="with --recommend: as apply --methods auto (default 0.03)")
    p.add_argument(
        "--auto-rungs",
        action="store_true",
        help="with --recommend: the rungs of the techniques' quality ladders are candidates too, as apply --auto-rungs",
    )
    p.add_argument(
        "--json",
        help="also write what was found (and with --recommend the choice per material) to this JSON file",
    )
    p.add_argument("--overwrite", action="store_true", help="allow --json to be an existing file")
    p.set_defaults(run=run)


def open_blend(path: str, scene_name: str | None = None):
    """Open ``path`` read-only in bpy and return the chosen scene; clear errors for bad input."""
    from .cli import CommandError, require_bpy

    bpy = require_bpy()
    if not os.path.isfile(path):
        raise CommandError(f"{path!r} does not exist or is not a file (expected a .blend file)")
    if not path.endswith(".blend"):
        raise CommandError(f"{path!r} is not a .blend file")
    try:
        # Scripts off whatever the preferences say: a .blend from elsewhere never runs code here.
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path), load_ui=False, use_scripts=False)
    except RuntimeError as exc:  # Blender's "File format is not supported", "Missing DNA block", ...
        reason = " ".join(str(exc).replace("Error:", " ").split()) or "unknown error"
        raise CommandError(
            f"{path!r} cannot be opened as a .blend file ({reason[:200]}): it is damaged, truncated or not a "
            "Blender file; open it in Blender to check, or use its backup (.blend1)"
        ) from None
    if bpy.app.autoexec_fail:  # what the blocked scripts drive keeps the value saved in the file
        print(
            f"sss_lab: note: {path!r}: its scripts were not run (SSS Lab opens files with scripts off;"
            f" Blender blocked {' '.join(bpy.app.autoexec_fail_message.split())[:200]!r}): what they drive keeps"
            " the value saved in the file",
            flush=True,
        )
    if scene_name is None:
        return bpy.context.scene
    scene = bpy.data.scenes.get(scene_name)
    if scene is None:
        raise CommandError(f"no scene {scene_name!r} in {path!r}; it has: {', '.join(s.name for s in bpy.data.scenes)}")
    return scene


def run(args) -> int:
    from .cli_options import check_at_least, read_resolution

    check_at_least(args, 1, "samples")
    resolution = read_resolution(args)
    from .cli import json_out_path

    json_out = json_out_path(args, {"the input .blend": args.blend})
    scene = open_blend(args.blend, args.scene)
    from ..blender.describe import sss_materials
    from ..blender.scan import recommendation, scan_report

    for line in scan_report(scene):
        print(line)
    plan = None
    if args.recommend:
        lines, plan = recommendation(
            scene,
            resolution=resolution,
            samples=args.samples,
            max_error=args.max_error,
            rungs=args.auto_rungs,
            log=None,
        )
        for line in lines:
            print(line)
    if json_out:
        import dataclasses
        import json

        from ..core.base import files
        from ..core.base.progress import saved_line

        data = {
            "scene": scene.name,
            "materials": [dataclasses.asdict(m) for m in sss_materials(scene)],
            "recommendation": plan.to_dict() if plan is not None else None,
        }
        files.write_text(json_out, json.dumps(data, indent=2, default=str))
        print(saved_line(json_out), flush=True)
    return 0
