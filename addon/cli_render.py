"""``python -m sss_lab render SCENE.blend --out DIR``: render the passes the techniques need.

Reads SCENE.blend (never written), renders per frame a multilayer EXR ``passes_####.exr`` with
exactly the passes the chosen techniques read, the subsurface materials rendered as plain
diffuse, and writes the scene description beside it (``passes_####.json``). Prints one
``Saved: '<path>'`` line per written file and a progress line per frame with the elapsed time
and the ETA. ``--skip-existing`` keeps the frames already written (a re-queued farm chunk) and
says which. Exit status: 0 done, 2 bad arguments or a scene it cannot render as asked, 3 no
material scatters light (nothing written).
"""

from __future__ import annotations

import os
import re
import sys


def add_parser(subparsers):
    from .cli_options import (
        add_blend,
        add_existing,
        add_frames,
        add_methods,
        add_render_device,
        add_resolution,
        add_samples,
        add_scene,
        add_seed,
        add_view_layer,
    )

    p = subparsers.add_parser(
        "render",
        help="render the passes the SSS techniques need from a .blend scene (needs bpy)",
        description=__doc__.split("\n\n", 1)[1],
    )
    add_blend(p)
    p.add_argument("--out", required=True, help="output folder (created if needed)")
    add_scene(p)
    add_view_layer(p, "view layer to render (default: the scene's active one)")
    add_frames(p)
    add_samples(
        p,
        "--pass-samples",
        old="--samples",
        help="Cycles samples of the passes (default: the scene's); adaptive sampling is off",
    )
    add_seed(p)
    add_resolution(p)
    add_methods(p, what="techniques whose passes to render")
    add_existing(p, "frames")
    add_render_device(p)
    p.set_defaults(run=run)


def _finished(out_dir: str, frame: int, techniques: list[str], samples: int | None, job: dict) -> str | None:
    """The passes file of ``frame`` when it and its scene description exist, the file is whole and
    it is this job's (then it is kept); None when the frame must be rendered (a file that does not
    read whole is rendered again). CommandError when the kept frame was rendered for other
    techniques, samples, seed, scene or size: skipping it would deliver files the job did not ask
    for. ``job``: what the frame must match besides ("scene": name, "size": (w, h), "seed": int or
    None, "file": the .blend file's name)."""
    from ..blender.render_passes import FILE_PATTERN
    from ..core.base.errors import InputError, SSSLabError
    from ..core.base.jsonfile import read_json
    from ..core.pipeline.sequence import frame_path, sidecar_path
    from ..core.scene.exr import read_passes
    from .cli import CommandError

    exr = os.path.join(out_dir, frame_path(FILE_PATTERN, frame))
    if not (os.path.isfile(exr) and os.path.isfile(sidecar_path(exr))):
        return None
    try:
        description = read_json(sidecar_path(exr), "a scene description")
        meta = description.get("meta", {})
        camera = description.get("camera", {})
    except InputError as exc:  # names the file and what is wrong
        raise CommandError(f"{exc}; pass --overwrite") from None
    except (OSError, ValueError, AttributeError) as exc:
        raise CommandError(f"{sidecar_path(exr)}: not a readable scene description ({exc}); pass --overwrite") from None
    missing = [t for t in techniques if t not in meta.get("techniques", [])]
    if missing:
        raise CommandError(
            f"{exr} exists but holds no passes for {', '.join(missing)} (it was rendered for "
            f"{', '.join(meta.get('techniques', [])) or 'unknown techniques'}); pass --overwrite or another --out"
        )
    differs = []
    if samples is not None and meta.get("samples") != samples:
        differs.append(f"{meta.get('samples')} samples, not {samples}")
    if job.get("seed") is not None and meta.get("seed") != job["seed"]:
        differs.append(f"seed {meta.get('seed')}, not {job['seed']}")
    if meta.get("scene") != job["scene"]:
        differs.append(f"scene {meta.get('scene')!r}, not {job['scene']!r}")
    # The .blend file by name (a farm may move it between nodes, not rename it).
    theirs = os.path.basename(str(meta.get("file") or ""))
    if theirs != job["file"]:
        differs.append(f"from {theirs or 'an unsaved file'!r}, not {job['file']!r}")
    size = (camera.get("width_px"), camera.get("height_px"))
    if size != tuple(job["size"]):
        differs.append(f"{size[0]}x{size[1]} pixels, not {job['size'][0]}x{job['size'][1]}")
    if differs:
        raise CommandError(
            f"{exr} exists but was rendered with {'; '.join(differs)}; pass --overwrite or another --out"
        )
    try:
        passes = read_passes(exr)
    except (SSSLabError, OSError, ValueError) as exc:  # cut short or damaged: rendered again
        print(f"render: {exr} does not read whole ({exc}): rendering frame {frame} again", flush=True)
        return None
    if (passes.shape[1], passes.shape[0]) != tuple(job["size"]):
        print(f"render: {exr} holds {passes.shape[1]}x{passes.shape[0]} pixels: rendering frame {frame} again")
        return None
    return exr


def run(args) -> int:
    from ..core.pipeline.sequence import parse_frames
    from .cli import EXIT_NOTHING_TO_DO, parse_methods, require_bpy
    from .cli_options import check_at_least, read_resolution
    from .cli_scan import open_blend

    require_bpy()
    techniques = parse_methods(args.methods)
    frames = parse_frames(args.frames) if args.frames else None
    check_at_least(args, 1, "pass_samples")
    check_at_least(args, 0, "seed")
    from ..blender import render_passes as rp

    resolution = read_resolution(args)
    scene = open_blend(args.blend, args.scene)
    from ..core.base.progress import Progress
    from .cli_options import render_device

    def log(line: str):
        print(line if line.startswith("Saved:") else f"render: {line}", flush=True)

    # The render's own lines count the frames it renders; the command counts every frame of the
    # chunk (kept ones too) and adds the elapsed time and the ETA to each frame's last line.
    done_line: list[str] = []

    def render_log(line: str):
        if re.match(r"\[\d+/\d+\] frame ", line):
            line = progress.position() + line[line.index("]") + 1 :]
        elif re.match(r"frame \S+ done in ", line):
            done_line.append(line)
            return
        log(line)

    def frame_done(_done: int, _total: int):
        log(f"{done_line.pop() if done_line else 'frame done'} ({progress.finish()})")

    out_dir = os.path.abspath(args.out)
    frames = frames or [scene.frame_current]
    progress = Progress(len(frames))
    todo = frames
    if args.skip_existing:
        render = scene.render
        size = resolution or (
            max(1, int(render.resolution_x * render.resolution_percentage / 100)),
            max(1, int(render.resolution_y * render.resolution_percentage / 100)),
        )
        job = {"scene": scene.name, "size": size, "seed": args.seed, "file": os.path.basename(args.blend)}
        todo = []
        for frame in frames:
            kept = _finished(out_dir, frame, techniques, args.pass_samples, job)
            if kept is None:
                todo.append(frame)
            else:
                log(
                    f"{progress.position()} frame {frame}: skipped, {os.path.basename(kept)} exists ({progress.skip()})"
                )
        if not todo:
            log(f"every frame exists in {out_dir}: nothing to render")
            return 0

    try:
        with render_device(args, scene, log):
            paths = rp.render_passes(
                scene,
                out_dir,
                techniques=techniques,
                frames=todo,
                samples=args.pass_samples,
                resolution=resolution,
                seed=args.seed,
                view_layer=args.view_layer,
                # With --skip-existing a frame with only one of its two files (a task killed
                # between them) is rendered again.
                overwrite=args.overwrite or args.skip_existing,
                log=render_log,
                progress=frame_done,
            )
    except rp.NoSubsurfaceError as exc:
        print(f"sss_lab render: {exc}", file=sys.stderr)
        return EXIT_NOTHING_TO_DO
    skipped = f", {progress.skipped} kept" if progress.skipped else ""
    log(f"{len(paths) // 2} frame(s) written to {out_dir}{skipped}")
    return 0
