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

import json
import math
import os

from ..core.base.progress import printable, saved_line


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


def _png_name(image_name: str, taken: set) -> str:
    import bpy

    base = bpy.path.clean_name(image_name) + "_bakers"
    name, k = base + ".png", 1
    while name in taken:
        k += 1
        name = f"{base}_{k}.png"
    taken.add(name)
    return name


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

    from ..blender.export_profiles import export_profiles, thickness_maps
    from ..core.base import files
    from ..core.study import png
    from ..core.study.profile_export import page

    data = export_profiles(scene, technique=args.technique, albedo_mode=args.albedo_mode, metres=m)
    if not data["materials"]:
        print("export-profiles: no material with subsurface scattering; nothing written", flush=True)
        return EXIT_NOTHING_TO_DO
    maps, taken = [], {"profiles.json", "profiles.md"}
    for item in thickness_maps(scene):
        values = item.pop("values", None)
        if values is not None:
            item["file"] = _png_name(item["image"], taken)
        maps.append((item, values))
    data["thickness_maps"] = [item for item, _ in maps]
    blend = os.path.realpath(os.path.abspath(args.blend))
    writes = [("profiles.json", json.dumps(data, indent=2)), ("profiles.md", page(data))]
    paths = [os.path.join(out, name) for name, _ in writes] + [
        os.path.join(out, item["file"]) for item, v in maps if v is not None
    ]
    for path in paths:  # every check before anything is written
        if os.path.realpath(path) == blend:
            raise CommandError(f"{printable(path)!r} is the input .blend; refusing to write over it")
        if os.path.lexists(path) and not args.overwrite:
            raise CommandError(f"{printable(path)!r} exists; refusing to overwrite it (pass --overwrite to allow it)")
    os.makedirs(out, exist_ok=True)
    for material in data["materials"]:
        for engine in ("hdrp", "unreal"):
            for note in material[engine]["notes"]:
                print(f"export-profiles: {printable(material['material'])}: {engine}: {printable(note)}", flush=True)
    for item, values in maps:
        if values is None:
            print(f"export-profiles: thickness image {printable(item['image'])}: {printable(item['error'])}")
            continue
        path = os.path.join(out, item["file"])
        files.write_bytes(path, png.encode_png16_gray(values))
        print(saved_line(path), flush=True)
    for name, text in writes:
        path = os.path.join(out, name)
        files.write_text(path, text)
        print(saved_line(path), flush=True)
    return 0
