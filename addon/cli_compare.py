"""``python -m sss_lab compare SCENE.blend --out DIR``: each technique against Cycles random walk."""

from __future__ import annotations

import os


def _methods(text: str) -> tuple[str, ...]:
    from ..core.scene.scene import SUBSURFACE_METHODS
    from .cli import CommandError

    names = list(dict.fromkeys(t.strip().upper() for t in text.split(",") if t.strip()))
    if names == ["ALL"]:
        from ..blender import compat

        return compat.subsurface_methods()  # those this Blender renders
    if "ALL" in names:
        raise CommandError(
            f"--calibrate-methods: 'all' stands for every subsurface method and stands alone: it cannot be"
            f" combined with other methods, got {text!r}; give all alone, or the methods wanted"
            f" ({', '.join(SUBSURFACE_METHODS)})"
        )
    unknown = [n for n in names if n not in SUBSURFACE_METHODS]
    if unknown:
        raise CommandError(
            f"--calibrate-methods: unknown {unknown}; expected some of {', '.join(SUBSURFACE_METHODS)}, or all alone"
        )
    return tuple(names)


def _counts(text: str, flag: str) -> tuple[int, ...]:
    """``"4,16"`` -> (4, 16); ``none`` or empty -> (); CommandError naming ``flag`` otherwise."""
    from .cli import CommandError

    if text.strip().lower() in ("", "none"):
        return ()
    try:
        values = tuple(int(t) for t in text.split(",") if t.strip())
    except ValueError:
        values = ()
    if not values or any(v < 1 for v in values):
        raise CommandError(f"{flag} {text!r}: expected sample counts >= 1, comma-separated (or none)")
    return values


def add_parser(subparsers):
    from .cli_options import add_blend, add_methods, add_render_device, add_resolution, add_samples, add_scene, add_seed

    p = subparsers.add_parser(
        "compare", help="compare each technique with Cycles random walk and write a report (needs bpy)"
    )
    add_blend(p)
    p.add_argument("--out", required=True, help="report folder (metrics.json, report.md, report.html, images)")
    p.add_argument(
        "--overwrite", action="store_true", help="replace the report of an earlier comparison in OUT (refused without)"
    )
    add_scene(p)
    add_resolution(p)
    add_samples(p, "--reference-samples", default=256, help="Cycles samples of the reference (default: 256)")
    add_samples(p, "--pass-samples", default=64, help="Cycles samples of the passes (default: 64)")
    p.add_argument(
        "--bias-samples",
        type=int,
        default=None,
        help="samples of a second set of passes that splits each error into bias and pass noise"
        " (default 4 x --pass-samples; 0: no split)",
    )
    add_seed(p, default=0, help="Cycles seed of the reference (default: 0; the noise floor uses +1)")
    p.add_argument("--box", type=int, default=2, help="box downsampling before the metrics (2)")
    add_methods(p, default="sta,ssss,burley", what="techniques to compare")
    p.add_argument("--cache", help="reference cache folder (default: OUT/cache)")
    p.add_argument(
        "--calibrate-methods",
        default="",
        help="also calibrate the mapping for these subsurface methods (comma-separated, or all):"
        " one more reference each",
    )
    p.add_argument(
        "--reference",
        metavar="EXR",
        help="a reference merged from seed parts (sss_lab reference + merge-reference, e.g. on a farm) instead of "
        "rendering one; its halves give the noise floor",
    )
    from .cli_options import add_one_frame

    add_one_frame(p, "compare")
    p.add_argument(
        "--no-eevee",
        action="store_true",
        help="leave EEVEE out (by default it is rendered with and without scattering and scored beside the"
        " techniques; it needs an OpenGL context, made through EGL when headless)",
    )
    add_samples(p, "--eevee-samples", default=None, help="EEVEE's render samples (default: the scene's own)")
    p.add_argument(
        "--denoise-samples",
        default="4,16",
        metavar="N,N",
        help="Cycles random walk at these samples denoised by OpenImageDenoise, beside the techniques, each at two"
        " seeds so that the denoiser's bias is shown apart from its noise (default: 4,16; none: leave them out)",
    )
    add_render_device(p)
    p.set_defaults(run=run)


#: The files of a finished report: their presence in --out means an earlier comparison's.
REPORT_FILES = ("metrics.json", "report.md", "report.html")


def _check_cache(args, out: str) -> None:
    """CommandError naming ``--cache`` (or ``--out``, whose ``cache`` folder is the default) when
    the reference cache cannot be a folder: checked before anything renders."""
    from ..core.base.files import not_a_folder
    from ..core.base.progress import printable
    from .cli import CommandError

    cache = os.path.abspath(args.cache) if args.cache else os.path.join(out, "cache")
    blocker = not_a_folder(cache)
    if blocker is None:
        return
    flag, value = ("--cache", args.cache) if args.cache else ("--out", args.out)
    if blocker != cache:
        where = f"lies under {printable(blocker)!r}, which is a file"
    elif args.cache:
        where = "is a file"
    else:
        where = "holds a file named cache where the reference cache goes (pass --cache to put it elsewhere)"
    raise CommandError(f"{flag} {printable(value)!r} {where}; expected a folder for the reference cache")


def run(args) -> int:
    from .cli import CommandError, parse_methods
    from .cli_scan import open_blend

    out = os.path.abspath(args.out)
    if os.path.exists(out) and not os.path.isdir(out):
        raise CommandError(f"--out {args.out!r} is a file; expected a folder for the report")
    _check_cache(args, out)
    earlier = [n for n in REPORT_FILES if os.path.lexists(os.path.join(out, n))]
    if earlier and not args.overwrite:
        raise CommandError(
            f"--out {args.out!r} holds the report of an earlier comparison ({', '.join(earlier)}); refusing to"
            " overwrite it (pass --overwrite to replace it, or choose another folder)"
        )
    # The method lists are read before the .blend file is: a misspelt list is said at once.
    techniques = tuple(parse_methods(args.methods))
    calibrate_methods = _methods(args.calibrate_methods)
    scene = open_blend(args.blend, args.scene)
    if args.frame is not None:
        scene.frame_set(args.frame)  # the file is only read: nothing to put back
    from ..blender.compare import CompareSettings, compare_job
    from ..blender.jobs import run as run_job
    from ..core.base.progress import Progress
    from .cli_options import read_resolution

    settings = CompareSettings(
        resolution=read_resolution(args),
        reference_samples=args.reference_samples,
        pass_samples=args.pass_samples,
        bias_samples=args.bias_samples,
        seed=args.seed,
        box=args.box,
        techniques=techniques,
        cache_dir=args.cache,
        calibrate_methods=calibrate_methods,
        reference_file=os.path.abspath(args.reference) if args.reference else None,
        eevee=not args.no_eevee,
        denoise_samples=_counts(args.denoise_samples, "--denoise-samples"),
        eevee_samples=args.eevee_samples,
    )
    from .cli_options import render_device

    try:
        with render_device(args, scene):
            counter: list[Progress] = []

            def progress(step) -> None:
                """``compare: [k/N] what comes next (k-1/N, elapsed, ETA)`` before each step."""
                if not counter:
                    counter.append(Progress(step.total))
                    status = "starting"
                else:
                    status = counter[0].finish()
                print(f"compare: [{step.done + 1}/{step.total}] {step.message} ({status})", flush=True)

            data = run_job(compare_job(scene, out, settings), progress)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    if not data["complete"]:
        print("The report is incomplete: " + "; ".join(data["notes"]))
        return 1
    return 0
