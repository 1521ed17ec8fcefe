"""``python -m sss_lab apply PASSES.exr --methods ...``: apply techniques to rendered passes.

Needs only NumPy and OpenEXR (a render-farm node without Blender). Parses and reports; the
work is ``core.pipeline.sequence.apply_file``. Prints one ``Saved: '<path>'`` line per written file (render
farms read it), progress per frame with the elapsed time and the ETA on stdout, and errors on
stderr. ``--skip-existing`` keeps the outputs already written (a re-queued farm chunk) and says
which. Exit status: 0 done,
1 some frames failed (the others are written), 2 bad arguments or input, 3 no material of
the scene scatters light (nothing written).
"""

from __future__ import annotations

import math
import os
import sys
import time
import traceback

from ..core.techniques.registry import TECHNIQUES


def add_parser(subparsers):
    from .cli_options import add_existing, add_frames, add_view_layer, deprecated_alias

    p = subparsers.add_parser(
        "apply",
        help="apply SSS techniques to rendered passes (NumPy and OpenEXR only, no Blender needed)",
        description=(
            "Apply subsurface-scattering techniques to a multilayer EXR of render passes (Blender 5.2 or "
            "4.5 layout) and write a new EXR with the input layers plus SSSLab.<method>.Image and "
            "SSSLab.<method>.SSS. Never overwrites its input. Exit status: 0 done, 1 some frames failed to "
            "be written or run, 2 bad arguments or input (every failed frame's input was bad), 3 no material "
            "scatters light (nothing written)."
        ),
    )
    p.add_argument("passes", help="the passes EXR; a frame pattern like passes_####.exr for a sequence")
    p.add_argument(
        "--methods",
        "--method",  # the old spelling, deprecated: --methods in every command
        dest="method",
        action=deprecated_alias("--method"),
        required=True,
        help=f"technique: {', '.join(TECHNIQUES)}, a comma-separated list, all (those whose passes are present),"
        " or auto (per material, the cheapest technique predicted to be within --max-error of the best)",
    )
    p.add_argument(
        "--max-error",
        type=float,
        default=None,
        help="with --methods auto: how much worse than the best predicted (or, with a fit, measured) error a"
        " cheaper choice may be (relative; default 0.03)",
    )
    p.add_argument(
        "--auto-rungs",
        action="store_true",
        help="with --methods auto: the cheaper rungs of each technique's quality ladder are candidates too (more time"
        " saved, further from the best technique)",
    )
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a technique parameter, repeatable: KEY=VALUE for the one technique that runs, TECHNIQUE.KEY=VALUE "
        "when several run (default: the technique's own). "
        + "; ".join(f"{name}: {', '.join(t.param_names)}" for name, t in TECHNIQUES.items()),
    )
    p.add_argument("--out", help="output EXR (with #### for a sequence); default: <input stem>.sss.exr")
    p.add_argument("--explain", action="store_true", help="print the plan (materials, kernels, samples) and stop")
    p.add_argument(
        "--description",
        metavar="JSON",
        help="scene description JSON (#### allowed; default: the .json beside each EXR)",
    )
    p.add_argument(
        "--albedo-mode",
        default="post",
        help="post (albedo after scattering, the default) or pre-post (square root before and after)",
    )
    add_frames(p, help="frames of a #### pattern, e.g. 1-10, 1-3,7 or 1-9:2 (default: every existing file)")
    add_view_layer(p, help="view layer to read (default: the first one in the file)")
    add_existing(p, "output files (never the input)")
    p.set_defaults(run=run)


def _outputs(args, frames):
    """Output path per (frame, input path); ValueError when a sequence would share one output."""
    from ..core.pipeline.sequence import default_output, frame_path, is_sequence

    if args.out is None:
        return [default_output(path) for _, path in frames]
    if len(frames) > 1 and not is_sequence(args.out):
        raise ValueError(f"--out {args.out!r}: several frames need a # frame pattern in the output name")
    return [frame_path(args.out, f) if f is not None else args.out for f, _ in frames]


def _reads_whole(path: str) -> str | None:
    """None when the EXR at ``path`` reads whole, else why not (cut short, damaged)."""
    from ..core.base.errors import SSSLabError
    from ..core.scene.exr import read_layers

    try:
        read_layers(path)
    except (SSSLabError, OSError, ValueError) as exc:
        return " ".join(str(exc).split())[:200]
    return None


def run(args) -> int:
    from ..core.base.errors import is_bad_input
    from ..core.base.progress import printable
    from ..core.pipeline.apply import ALBEDO_MODES
    from ..core.pipeline.sequence import apply_file, frame_path, parse_frames, sequence_frames
    from ..core.techniques.registry import parse_params
    from .cli import EXIT_NOTHING_TO_DO, parse_methods

    techniques = parse_methods(args.method, allow_auto=True)
    said: set = set()  # the scene description's notes already printed
    if args.max_error is not None and techniques != ["auto"]:
        raise ValueError(f"--max-error {args.max_error}: only --methods auto takes it")
    if args.auto_rungs and techniques != ["auto"]:
        raise ValueError("--auto-rungs: only --methods auto takes it")
    if args.max_error is not None and not (math.isfinite(args.max_error) and args.max_error >= 0):
        raise ValueError(f"--max-error: expected a number >= 0 (0.05 = within 5 % of the best), got {args.max_error}")
    if args.param and "auto" in techniques:
        raise ValueError(f"--param {args.param[0]}: --methods auto chooses each technique's parameters itself")
    params = parse_params(args.param, [t for t in techniques if t in TECHNIQUES])
    if args.albedo_mode not in ALBEDO_MODES:
        raise ValueError(f"--albedo-mode: {args.albedo_mode!r} is not one of {', '.join(ALBEDO_MODES)}")
    frames = sequence_frames(args.passes, parse_frames(args.frames) if args.frames else None)
    outputs = _outputs(args, frames)
    for (_, path), out in zip(frames, outputs, strict=True):
        if os.path.exists(path) and os.path.exists(out) and os.path.samefile(path, out):
            raise FileExistsError(f"the output {out} is the input; refusing to overwrite it")

    from ..core.base.progress import Progress, saved_line

    failed = nothing = bad_input = 0
    total = len(frames)
    # auto on a sequence: the first frame's choice is kept, so that no material switches technique mid-shot.
    keep = None
    progress = Progress(total)
    for (frame, path), out in zip(frames, outputs, strict=True):
        what = f"frame {frame}" if frame is not None else os.path.basename(path)
        redo = False
        if args.skip_existing and not args.explain and os.path.exists(out):
            whole = _reads_whole(out)
            if whole is None:
                kept = os.path.basename(out)
                print(f"apply: {progress.position()} {what}: skipped, {kept} exists ({progress.skip()})")
                continue
            print(f"apply: {out} does not read whole ({whole}): applying {what} again", flush=True)
            redo = True
        print(f"apply: {progress.position()} {what}: {path}", flush=True)
        started = time.perf_counter()
        description = args.description
        scene_path = frame_path(description, frame) if description and frame is not None else description
        try:
            result = apply_file(
                path,
                techniques,
                out_path=out,
                scene_path=scene_path,
                albedo_mode=args.albedo_mode,
                explain=args.explain,
                overwrite=args.overwrite or redo,
                skip_missing=args.method.strip() == "all",
                view_layer=args.view_layer,
                max_error=args.max_error,
                auto_rungs=args.auto_rungs,
                auto_keep=keep,
                params=params,
            )
        except (OSError, ValueError, KeyError) as exc:
            failed += 1
            # A bad input (a damaged or missing file, a wrong value, an existing output without
            # --overwrite) rather than a failed write.
            bad_input += is_bad_input(exc)
            message = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
            if not message.startswith(path):
                message = f"{path}: {message}"
            print(f"sss_lab apply: error: {message}", file=sys.stderr, flush=True)
            progress.finish()
            continue
        except Exception:  # a bug: report it with its traceback, and go on with the other frames
            failed += 1
            print(f"sss_lab apply: internal error on {path}:", file=sys.stderr)
            traceback.print_exc()
            progress.finish()
            continue
        if "auto" in result.plans and keep is None:
            keep = result.plans["auto"].chosen
        for technique, reason in result.skipped.items():
            print(f"  {technique}: skipped: {reason}")
        if result.nothing_to_do:
            nothing += 1
            print(
                "  no material in the scene description scatters light (Subsurface Weight, Scale and the"
                " largest Radius channel must all be > 0): nothing written",
                flush=True,
            )
            for line in _why_not(result):
                print(f"  {printable(line)}", flush=True)
            progress.finish()
            continue
        # Said once per file (every technique's plan reads the same pass); --explain says it per plan.
        index_warning = next((p.index_warning for p in result.plans.values() if p.index_warning), None)
        if index_warning and not args.explain:
            print(f"  warning: {printable(index_warning)}", flush=True)
        for p in result.plans.values():
            if args.explain:
                print("\n".join("  " + line for line in p.explain().splitlines()))
            else:
                applied = p.applied
                if p.technique == "auto":
                    for c in p.choices:
                        print(f"  auto: material {c.features.name!r}: {c.chosen} ({c.reason})")
                names = (
                    ", ".join(printable(m.material.name or str(m.material.index)) for m in applied) or "none on screen"
                )
                extra = f"; {p.nonfinite_pixels} NaN/Inf pixels left as they are" if p.nonfinite_pixels else ""
                if p.overflow_pixels:
                    extra += f"; {p.overflow_pixels} pixels overflowed float32 (light near 3.4e38), left as they were"
                if p.negative_pixels:
                    extra += (
                        f"; warning: {p.negative_pixels} pixels whose diffuse passes exceed Combined (the passes"
                        " disagree) would have gone negative: set to 0"
                    )
                print(f"  {p.technique}: {len(applied)} material(s) computed ({names}){extra}")
                for m in applied:
                    name = m.material.name or m.material.index
                    if m.warning:
                        print(f"  {p.technique}: warning: material {name!r}: {m.warning}")
                    for note in m.material.notes:
                        if (name, note) not in said:  # once per run, not per technique or frame
                            said.add((name, note))
                            print(f"  note: material {name!r}: {note}")
        if result.written:
            print(saved_line(result.out_path), flush=True)
        print(f"apply: {what} done in {time.perf_counter() - started:.2f} s ({progress.finish()})", flush=True)
    if failed:
        print(f"sss_lab apply: {failed} of {total} file(s) failed", file=sys.stderr)
        return 2 if bad_input == failed else 1
    if nothing:
        return EXIT_NOTHING_TO_DO
    return 0


def _why_not(result) -> list[str]:
    """Per material of the scene description, which of its inputs keeps it from scattering."""
    lines = []
    for m in getattr(result.scene, "materials", ()) or ():
        zero = [
            name
            for name, value in (
                ("subsurface_weight", m.subsurface_weight),
                ("subsurface_scale", m.subsurface_scale),
                ("largest subsurface_radius channel", max(m.subsurface_radius)),
            )
            if not value > 0
        ]
        if zero:
            lines.append(f"material {m.name or m.index!r}: " + ", ".join(f"{name} = 0" for name in zero))
    return lines
