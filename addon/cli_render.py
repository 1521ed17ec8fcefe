"""``python -m sss_lab render SCENE.blend --out DIR``: render the passes the techniques need.

Reads SCENE.blend (never written), renders per frame a multilayer EXR ``passes_####.exr`` with
exactly the passes the chosen techniques read, the subsurface materials rendered as plain
diffuse, and writes the scene description beside it (``passes_####.json``). Prints one
``Saved: PATH`` line per written file. Exit status: 0 done, 2 bad arguments or a scene it
cannot render as asked, 3 no material scatters light (nothing written).
"""

from __future__ import annotations

import sys


def add_parser(subparsers):
    p = subparsers.add_parser(
        "render",
        help="render the passes the SSS techniques need from a .blend scene (needs bpy)",
        description=__doc__.split("\n\n", 1)[1],
    )
    p.add_argument("blend", help="the .blend file to read (never written)")
    p.add_argument("--out", required=True, help="output folder (created if needed)")
    p.add_argument("--scene", help="scene name (default: the file's active scene)")
    p.add_argument("--view-layer", help="view layer to render (default: the scene's active one)")
    p.add_argument("--frames", help="frames, e.g. 1-10 or 1-3,7 (default: the scene's current frame)")
    p.add_argument("--samples", type=int, help="Cycles samples (default: the scene's); adaptive sampling is off")
    p.add_argument("--seed", type=int, help="Cycles seed (default: the scene's)")
    p.add_argument("--resolution", help="WIDTHxHEIGHT at 100%% (default: the scene's resolution)")
    p.add_argument(
        "--methods",
        default="all",
        help="techniques whose passes to render: sta, ssss, burley, a comma-separated list, or all (default)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace passes files already in the folder")
    p.set_defaults(run=run)


def run(args) -> int:
    from ..core.sequence import parse_frames
    from .cli import EXIT_NOTHING_TO_DO, CommandError, parse_methods, require_bpy
    from .cli_scan import open_blend

    require_bpy()
    techniques = parse_methods(args.methods)
    frames = parse_frames(args.frames) if args.frames else None
    if args.samples is not None and args.samples < 1:
        raise CommandError(f"--samples: expected an integer >= 1, got {args.samples}")
    if args.seed is not None and args.seed < 0:
        raise CommandError(f"--seed: expected an integer >= 0, got {args.seed}")
    from ..blender import render_passes as rp

    if args.resolution is not None:
        try:
            resolution = rp.parse_resolution(args.resolution)
        except ValueError as exc:
            raise CommandError(f"--resolution: {exc}") from None
    else:
        resolution = None
    scene = open_blend(args.blend, args.scene)

    def log(line: str):
        print(line if line.startswith("Saved:") else f"render: {line}", flush=True)

    try:
        paths = rp.render_passes(
            scene,
            args.out,
            techniques=techniques,
            frames=frames,
            samples=args.samples,
            resolution=resolution,
            seed=args.seed,
            view_layer=args.view_layer,
            overwrite=args.overwrite,
            log=log,
        )
    except rp.NoSubsurfaceError as exc:
        print(f"sss_lab render: {exc}", file=sys.stderr)
        return EXIT_NOTHING_TO_DO
    print(f"render: {len(paths) // 2} frame(s) written to {args.out}")
    return 0
