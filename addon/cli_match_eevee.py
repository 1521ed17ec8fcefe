"""``python -m sss_lab match-eevee SCENE.blend --out OUT.blend``: match EEVEE to Cycles per material.

Renders the scene's own view with Cycles random walk and without scattering, and with EEVEE,
and gives each subsurface material an EEVEE-only branch (a Material Output targeting EEVEE beside
the one Cycles renders) whose Radius and Base Color make EEVEE's SSS effect match Cycles' on that
view (``blender/match_eevee.py``). Cycles renders OUT.blend exactly as it rendered SCENE.blend.
``--cache DIR`` keeps the renders for a later match of the same scene and settings. ``--remove``
takes a match out of every material instead, rendering nothing. OUT may not be an existing file
unless ``--overwrite`` says so. Exit status: 0 every material on screen matched (or the matches
removed), 1 some kept as authored (each named on one line), 2 bad arguments or input.
"""

from __future__ import annotations

import json
import os

from ..core.base.progress import saved_line


def add_parser(subparsers):
    from .cli_options import add_blend_to_blend, add_resolution, add_samples, add_scene, add_seed

    p = subparsers.add_parser(
        "match-eevee",
        help="match EEVEE's subsurface scattering to Cycles' random walk per material, in an EEVEE-only"
        " branch (needs bpy)",
        description=__doc__.split("\n\n", 1)[1],
    )
    add_blend_to_blend(p, out_help="the .blend file to write, with the EEVEE branches")
    add_scene(p)
    add_samples(p, default=64, help="Cycles random-walk samples of the effect to match (default: 64)")
    add_samples(p, "--pass-samples", default=16, help="Cycles samples without scattering (default: 16)")
    add_samples(p, "--eevee-samples", default=None, help="EEVEE's render samples (default: the scene's own)")
    add_resolution(p, help="render size WIDTHxHEIGHT for the match (default: the scene's)")
    add_seed(p, default=0, help="Cycles seed (default: 0)")
    p.add_argument(
        "--cache",
        help="keep the renders in this folder and reuse those of an earlier match of the same scene and settings"
        " (default: a temporary folder, removed at the end)",
    )
    p.add_argument("--remove", action="store_true", help="remove the EEVEE branches of an earlier match instead")
    p.add_argument("--json", help="also write what was matched per material to this JSON file")
    p.set_defaults(run=run)


def _cache_folder(value: str | None) -> str | None:
    """``--cache`` as an absolute path, or CommandError naming it when it cannot be a folder
    (checked before the scene opens or anything renders)."""
    if value is None:
        return None
    from ..core.base.files import not_a_folder
    from ..core.base.progress import printable
    from .cli import CommandError

    cache = os.path.abspath(value)
    blocker = not_a_folder(cache)
    if blocker is not None:
        where = "is a file" if blocker == cache else f"lies under {printable(blocker)!r}, which is a file"
        raise CommandError(f"--cache {printable(value)!r} {where}; expected a folder for the renders")
    return cache


def run(args) -> int:
    from .cli import CommandError
    from .cli_options import read_blend_out, read_resolution, save_blend
    from .cli_scan import open_blend

    out = read_blend_out(args)
    from .cli import json_out_path

    json_out = json_out_path(args, {"the input .blend": args.blend, "--out": out})
    resolution = read_resolution(args)
    cache = _cache_folder(args.cache)
    scene = open_blend(args.blend, args.scene)

    import bpy

    from ..blender import match_eevee as match
    from ..core.base import files
    from ..core.base.errors import InputError

    def log(line):
        print(f"match-eevee: {line}", flush=True)

    if args.remove:
        removed = [m.name for m in bpy.data.materials if match.remove_match(m)]
        log(f"removed the EEVEE branch of {len(removed)} material(s)" + (f": {', '.join(removed)}" if removed else ""))
        data: dict = {"removed": removed}
        code = 0
    else:
        settings = match.MatchSettings(
            resolution=resolution,
            cycles_samples=args.samples,
            pass_samples=args.pass_samples,
            eevee_samples=args.eevee_samples,
            seed=args.seed,
            cache_dir=cache,
        )
        try:
            data = match.match_eevee(scene, settings, log=log)
        except InputError as exc:
            raise CommandError(str(exc)) from None
        code = 0 if all(not m["skipped"] for m in data["materials"].values()) else 1
    os.makedirs(os.path.dirname(out), exist_ok=True)
    files.check_interrupted()  # a match cut short by Ctrl-C is not saved
    save_blend(out, overwrite=args.overwrite)
    print(saved_line(out), flush=True)
    if json_out:
        files.write_text(json_out, json.dumps(data, indent=2, default=str))
        print(saved_line(json_out), flush=True)
    return code
