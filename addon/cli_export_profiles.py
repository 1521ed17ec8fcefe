"""``python -m sss_lab export-profiles SCENE.blend --out DIR``: each material's profile for the engines.

Writes DIR/profiles.json (per subsurface material: Burley's d and the fit's base-colour gain, Unity
HDRP's diffusion profile, Unreal's Subsurface Profile and EEVEE's inputs) and DIR/profiles.md (the
same as a page to type from), and each thickness image SSS Lab baked as
DIR/<image>_bakers.png, a 16-bit map in the bakers' convention (white = thick, the slab
thickness over the bake distance: HDRP's Thickness Remap 0..D mm in profiles.json gives it back in
millimetres). The profile is the material's as the passes read it, with the fit ``calibrate``
stored on it for --technique. Units and formulas: docs/references.md §19. The .blend is never
written; no file in DIR is replaced unless --overwrite is given. Exit status: 0 written, 2 bad
arguments or input, 3 no material with subsurface scattering (nothing written).
"""

from __future__ import annotations

import math
import os

from ..core.base.progress import saved_line


def add_parser(subparsers):
    from .cli_options import add_blend, add_scene

    p = subparsers.add_parser(
        "export-profiles",
        help="export each material's profile as Unity HDRP, Unreal and EEVEE values, and the baked thickness"
        " maps in the bakers' convention (needs bpy)",
        description=__doc__.split("\n\n", 1)[1],
    )
    add_blend(p)
    add_scene(p)
    p.add_argument("--out", required=True, help="the folder to write profiles.json, profiles.md and the maps into")
    p.add_argument("--overwrite", action="store_true", help="replace files in OUT that already exist")
    p.add_argument(
        "--technique",
        default="burley",
        help="whose fit (stored by calibrate) sets the profile's width and gain (default: burley)",
    )
    p.add_argument(
        "--albedo-mode",
        choices=("post", "pre-post"),
        default="post",
        help="how the engine applies the albedo: post (HDRP Post-Scatter) or pre-post (Pre- and Post-Scatter)",
    )
    p.add_argument(
        "--metres-per-unit",
        type=float,
        default=None,
        help="the size of one scene unit in metres (default: the scene's Unit Scale)",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    from ..core.techniques.registry import check_technique
    from .cli import EXIT_NOTHING_TO_DO, CommandError
    from .cli_scan import open_blend

    try:
        check_technique(args.technique)
    except ValueError as exc:
        raise CommandError(f"--technique: {exc}") from None
    m = args.metres_per_unit
    if m is not None and not (math.isfinite(m) and m > 0):
        raise CommandError(f"--metres-per-unit {m!r}: expected a number > 0")
    out = os.path.abspath(args.out)
    if os.path.exists(out) and not os.path.isdir(out):
        raise CommandError(f"--out {args.out!r} is a file; expected a folder")
    scene = open_blend(args.blend, args.scene)

    from ..blender.export_profiles import write_export
    from ..core.base.errors import InputError

    try:
        _, written = write_export(
            scene,
            out,
            overwrite=args.overwrite,
            technique=args.technique,
            albedo_mode=args.albedo_mode,
            metres=m,
            protect=(args.blend,),
            log=lambda line: print(f"export-profiles: {line}", flush=True),
        )
    except InputError as exc:
        raise CommandError(str(exc)) from None
    if not written:
        print("export-profiles: no material with subsurface scattering; nothing written", flush=True)
        return EXIT_NOTHING_TO_DO
    for path in written:
        print(saved_line(path), flush=True)
    return 0
