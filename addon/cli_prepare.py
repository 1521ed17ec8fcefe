"""``python -m sss_lab prepare``: compile the kernels into the cache before the first frame needs
them (``core/study/prepare.py``): on a render-farm node before its first task, or after installing or
updating SSS Lab. No Blender needed."""

from __future__ import annotations


def add_parser(subparsers):
    from .cli_options import deprecated_alias

    p = subparsers.add_parser(
        "prepare",
        help="compile the compiled kernels into their on-disk cache ahead of the first frame (no bpy needed)",
    )
    p.add_argument(
        "--methods",
        "--method",  # the old spelling, deprecated: --methods in every command
        dest="method",
        action=deprecated_alias("--method"),
        default="all",
        help="the techniques to prepare: all (default) or a comma-separated list of sta, ssss, burley, combined",
    )
    p.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="compile in this many processes side by side (default 1; Numba compiles on one core, so up to one "
        "per core and per technique helps on an empty cache)",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    from ..core.study.prepare import MAX_JOBS, prepare_kernels
    from .cli import CommandError, parse_methods

    if not 1 <= args.jobs <= MAX_JOBS:
        raise CommandError(f"--jobs {args.jobs}: expected a whole number from 1 to {MAX_JOBS}")
    names = parse_methods(args.method)
    everything = args.method.strip() == "all"
    result = prepare_kernels(
        None if everything else names, log=lambda line: print(f"prepare: {line}", flush=True), jobs=args.jobs
    )
    for name, seconds in sorted(result["kernels"].items(), key=lambda kv: -kv[1]):
        print(f"prepare: {name:24s} {seconds:7.2f} s")
    print(
        f"prepare: {len(result['kernels'])} kernels ready in {result['seconds']:.1f} s, cached in {result['cache_dir']}"
    )
    return 0
