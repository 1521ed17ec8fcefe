"""``python -m sss_lab reference SCENE.blend --out DIR --seeds 1-8 --samples 64``: the Cycles
reference in parts, one per seed (a farm task each).

Renders the scene as it is (its own subsurface method), Combined only, adaptive sampling and
denoising off, once per seed, into ``DIR/reference_seed_#####.exr`` with a JSON beside it
(samples, seed, frame, size, the scene's fingerprint). ``merge-reference`` merges the parts into
one reference of the summed samples with its noise floor; ``compare --reference`` uses it.
Prints ``Saved: '<path>'`` per written file and a progress line per seed with the elapsed time
and the ETA.
"""

from __future__ import annotations


def add_parser(subparsers):
    from .cli_options import add_blend, add_existing, add_render_device, add_resolution, add_scene

    p = subparsers.add_parser(
        "reference",
        help="render the comparison's Cycles reference in parts, one per seed (needs bpy)",
        description=__doc__.split("\n\n", 1)[1],
    )
    add_blend(p)
    p.add_argument("--out", required=True, help="output folder (created if needed)")
    add_scene(p)
    p.add_argument("--seeds", required=True, help="Cycles seeds, one part each: e.g. 1-8 or 3 or 1,4")
    p.add_argument("--samples", type=int, required=True, help="Cycles samples per part")
    from .cli_options import add_one_frame

    add_one_frame(p, "render")
    add_resolution(p)
    add_existing(p, "parts")
    add_render_device(p)
    p.set_defaults(run=run)


def run(args) -> int:
    from ..core.pipeline.sequence import parse_frames
    from .cli import CommandError, require_bpy
    from .cli_options import check_at_least, read_resolution, render_device
    from .cli_scan import open_blend

    require_bpy()
    try:
        seeds = parse_frames(args.seeds)
    except ValueError as exc:
        raise CommandError(f"--seeds: {exc}".replace("frames: ", "")) from None
    check_at_least(args, 1, "samples")
    resolution = read_resolution(args)
    scene = open_blend(args.blend, args.scene)
    from ..blender.reference import render_reference_parts

    def log(line: str):
        print(line if line.startswith("Saved:") else f"reference: {line}", flush=True)

    with render_device(args, scene, log):
        render_reference_parts(
            scene,
            args.out,
            seeds=seeds,
            samples=args.samples,
            resolution=resolution,
            frame=args.frame,
            skip_existing=args.skip_existing,
            overwrite=args.overwrite,
            log=log,
        )
    return 0
