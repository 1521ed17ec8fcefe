"""``python -m sss_lab calibrate SCENE.blend --out OUT.blend``: fit each subsurface material to Cycles.

Renders the scene's own view with Cycles random walk at a few dozen samples and the passes,
fits per subsurface material and technique a per-channel gain, a scale on d and (combined
technique) the light from behind, and writes OUT.blend with the fitted values stored on the
materials. ``render`` and ``apply`` on OUT.blend use them with no extra option. OUT may not be
an existing file unless ``--overwrite`` says so. Exit status: 0 every material fitted, 1 some
could not be (each named on one line, left unchanged), 2 bad arguments or input.
"""

from __future__ import annotations

import json
import os

from ..core.base.progress import saved_line


def add_parser(subparsers):
    from ..core.pipeline.fit_params import FIT_PARAMETERS
    from ..core.study.fit import BUDGET, MAX_SAMPLES, REFERENCE_SAMPLES
    from .cli_options import add_blend_to_blend, add_resolution, add_samples, add_scene, add_seed

    p = subparsers.add_parser(
        "calibrate",
        help="fit each subsurface material's parameters to a short Cycles random-walk render (needs bpy)",
        description=__doc__.split("\n\n", 1)[1],
    )
    add_blend_to_blend(p, out_help="the .blend file to write, with the fitted values")
    add_scene(p)
    add_samples(p, default=32, help="Cycles random-walk samples to fit to (default: 32)")
    add_samples(
        p,
        "--max-samples",
        help="for the fits the held-out check refuses: render again up to this many samples in all, within"
        f" --budget (default: {MAX_SAMPLES}, or --samples when higher; equal to --samples: never)",
    )
    p.add_argument(
        "--budget",
        type=float,
        default=None,
        metavar="SHARE",
        help=f"the most the fit may cost, as a share of a {REFERENCE_SAMPLES}-sample render of the view, when it"
        f" renders again (default: {BUDGET:g})",
    )
    add_samples(
        p,
        "--pass-samples",
        default=16,
        help="Cycles samples of the passes (default: 16; the fit averages 2 x 2 blocks, and on the fidelity suite"
        " 16 and 64 samples give the same share removed on frame A within 1 point)",
    )
    p.add_argument(
        "--methods",
        default="burley,combined",
        help=f"techniques to fit: some of {', '.join(FIT_PARAMETERS)} (default: burley,combined)",
    )
    add_resolution(p, help="render size WIDTHxHEIGHT for the fit (default: the scene's)")
    add_seed(p, default=0, help="Cycles seed (default: 0)")
    p.add_argument("--json", help="also write the fit results (errors, values, times) to this JSON file")
    p.set_defaults(run=run)


def run(args) -> int:
    from .cli_options import read_blend_out, read_resolution
    from .cli_scan import open_blend

    out = read_blend_out(args)
    from .cli import json_out_path

    json_out = json_out_path(args, {"the input .blend": args.blend, "--out": out})
    resolution = read_resolution(args)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    scene = open_blend(args.blend, args.scene)

    from ..blender.calibrate import calibrate

    def log(line):
        print(f"calibrate: {line}", flush=True)

    data = calibrate(
        scene,
        techniques=methods,
        samples=args.samples,
        pass_samples=args.pass_samples,
        **{k: v for k, v in (("max_samples", args.max_samples), ("budget", args.budget)) if v is not None},
        resolution=resolution,
        seed=args.seed,
        log=log,
    )
    for line in data["problems"]:
        print(f"sss_lab calibrate: {line}", flush=True)
    if data["results"]:
        os.makedirs(os.path.dirname(out), exist_ok=True)
        from ..core.base import files

        files.check_interrupted()  # a fit cut short by Ctrl-C is not saved
        from .cli_options import save_blend

        save_blend(out, overwrite=args.overwrite)  # written, read back, then moved into place
        print(saved_line(out), flush=True)
    else:
        print("sss_lab calibrate: no material could be fitted; nothing written", flush=True)
    if json_out:
        from ..core.base import files

        files.write_text(json_out, json.dumps(data, indent=2, default=str))
        print(saved_line(json_out), flush=True)
    s = data["seconds"]
    line = f"calibrate: Cycles {s['reference']:.1f} s, passes {s['passes']:.1f} s, fit {s['fit']:.1f} s"
    if "start_up" in s:
        line += f", start-up {s['start_up']:.1f} s (once per process: imports, compiled kernels, tables)"
    if "pilot" in s:
        line += f", pilot {s['pilot']:.1f} s"
    if "more" in s:
        line += f", more samples {s['more']:.1f} s, second fit {s['fit_more']:.1f} s"
    print(line, flush=True)
    return 0 if data["results"] and not data["problems"] else 1
