"""``python -m sss_lab bake-thickness SCENE.blend --out OUT.blend``: bake thickness maps headless.

Reads SCENE.blend, bakes the named objects (default: every local mesh object the scene
renders that carries a subsurface material; floors and occluders need no map) and writes the
result to OUT.blend. OUT may not be an existing file — the input least of all — unless
``--overwrite`` says so. Images go to ``--image-dir`` (default: ``OUT_thickness/`` beside OUT),
referenced relative to OUT. Prints ``Saved: '<path>'`` for every file written (images, their
JSON, OUT).
"""

from __future__ import annotations

import argparse
import errno
import os
import sys
import time

from ..core.scene.thickness import CONVENTIONS, SOURCES, TARGETS, BakeSettings

_FORMATS = {"exr": "OPEN_EXR", "png": "PNG"}


def add_parser(subparsers):
    from .cli_options import add_blend_to_blend, add_render_device, add_samples, add_scene

    p = subparsers.add_parser(
        "bake-thickness",
        help="bake thickness maps (inverted-normal AO) of a .blend scene into a new .blend (needs bpy)",
        description=__doc__.split("\n\n", 1)[1],
    )
    add_blend_to_blend(p, out_help="the .blend file to write")
    add_scene(p)
    p.add_argument(
        "--objects",
        nargs="+",
        metavar="NAME",
        help="objects to bake (default: every local mesh object that renders and carries a subsurface material)",
    )
    p.add_argument("--target", choices=TARGETS, default="attribute", help="default: %(default)s")
    p.add_argument("--convention", choices=tuple(CONVENTIONS), default="translucency", help="default: %(default)s")
    p.add_argument(
        "--source",
        choices=tuple(SOURCES),
        default=None,
        help="ray: the distance to the far side along the inward normals, as a slab of that thickness"
        " bakes (attribute target; the default there); ao: inside ambient occlusion (the default for an"
        " image target)",
    )
    add_samples(p, default=32, help="AO rays per vertex or texel (default: %(default)s)")
    p.add_argument(
        "--distance",
        type=float,
        default=0.0,
        help="AO distance, scene units (default 0: a quarter of the bounding-box diagonal)",
    )
    p.add_argument(
        "--only-local",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="only the object itself occludes (default); --no-only-local: every rendered object does",
    )
    p.add_argument("--attribute", default="Thickness", help="attribute name (default: %(default)s)")
    # Not --resolution: that is a render size WIDTHxHEIGHT in every command.
    p.add_argument(
        "--image-size", type=int, default=1024, metavar="PIXELS", help="image width and height (default: %(default)s)"
    )
    p.add_argument("--margin", type=int, default=16, help="image margin in pixels (default: %(default)s)")
    p.add_argument("--format", choices=tuple(_FORMATS), default="exr", help="exr: float32; png: 16-bit")
    p.add_argument("--image-dir", help="folder for the images (default: OUT_thickness beside OUT)")
    p.add_argument("--no-materials", action="store_true", help="do not add the maps to the objects' materials")
    add_render_device(p)
    p.set_defaults(run=run)


def _default_objects(scene) -> list[str]:
    from ..blender.bake import subsurface_meshes

    return [o.name for o in subsurface_meshes(scene)]


def run(args) -> int:
    from .cli import CommandError
    from .cli_options import read_blend_out
    from .cli_scan import open_blend

    out = read_blend_out(args)
    _check_writable(os.path.dirname(out))
    image_dir = os.path.abspath(args.image_dir or os.path.splitext(out)[0] + "_thickness")
    settings = BakeSettings(
        target=args.target,
        convention=args.convention,
        source=args.source,
        samples=args.samples,
        distance_su=args.distance,
        only_local=args.only_local,
        attribute_name=args.attribute,
        resolution_px=args.image_size,
        margin_px=args.margin,
        image_format=_FORMATS[args.format],
        image_folder=image_dir,
        link_materials=not args.no_materials,
        overwrite=bool(args.overwrite),
    )
    scene = open_blend(args.blend, args.scene)
    import bpy

    if scene != bpy.context.scene:
        window = bpy.context.window or next(iter(bpy.context.window_manager.windows), None)
        if window is None:
            raise CommandError(f"cannot make scene {scene.name!r} active to bake it (no window); save it as active")
        window.scene = scene
    from ..blender.bake import bake_thickness

    names = args.objects or _default_objects(scene)
    if not names:
        raise CommandError(
            f"scene {scene.name!r} has no local mesh object that renders with a subsurface material (Subsurface"
            " Weight > 0); name objects with --objects"
        )
    t0 = time.perf_counter()

    def log(line):
        print(f"bake-thickness: {line}", flush=True)

    from ..core.base.progress import saved_line
    from .cli_options import render_device

    with render_device(args, scene, log):  # put back before saving: OUT keeps the scene's own settings
        results = bake_thickness(bpy.context, names, settings, log=log)
    counts = {s: sum(r.status == s for r in results) for s in ("baked", "shared", "skipped", "failed", "cancelled")}
    base = os.path.dirname(bpy.data.filepath)
    for r in results:
        image = bpy.data.images.get(r.data) if r.status == "baked" and r.target == "image" else None
        if image is not None:
            try:  # relative to the input here; Blender remaps it relative to OUT when saving
                image.filepath_raw = bpy.path.relpath(r.filepath, start=base)
            except ValueError:  # another drive: keep the absolute path
                pass
    for r in results:
        if r.status == "failed":  # an error: one line on stderr each
            print(f"sss_lab bake-thickness: {r}", file=sys.stderr, flush=True)
        elif r.status in ("skipped", "cancelled"):
            print(f"bake-thickness: {r}", flush=True)
    if not counts["baked"] and not counts["shared"]:
        tally = ", ".join(f"{n} {s}" for s, n in counts.items() if n)
        message = f"nothing was baked ({tally}; the reasons are above); {out} not written"
        if any(r.write_failed for r in results):  # a failed write (exit 1), not bad input (exit 2)
            from ..core.base.errors import OutputError

            raise OutputError(message)
        raise CommandError(message)
    from ..core.base import files

    files.check_interrupted()  # a bake cut short by Ctrl-C is not saved
    from .cli_options import save_blend

    save_blend(out, overwrite=args.overwrite)  # written, read back, then moved into place
    for r in results:
        if r.status == "baked" and r.filepath:
            print(saved_line(r.filepath))
            if os.path.isfile(r.filepath + ".json"):
                print(saved_line(r.filepath + ".json"))
    print(saved_line(out))
    summary = ", ".join(f"{n} {s}" for s, n in counts.items() if n)
    print(f"bake-thickness: {summary} in {time.perf_counter() - t0:.2f} s")
    return 1 if counts["failed"] else 0


def _check_writable(folder: str) -> None:
    """Refuse at once an output folder on a read-only file system or without permission, rather
    than after baking every object."""
    from ..core.base.errors import OutputError, describe_os_error

    existing = folder
    while existing and not os.path.isdir(existing):
        existing = os.path.dirname(existing)
    if existing and not os.access(existing, os.W_OK):
        code = errno.EROFS if _read_only(existing) else errno.EACCES
        raise OutputError(code, describe_os_error(OSError(code, os.strerror(code)), existing))


def _read_only(folder: str) -> bool:
    try:
        return bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except OSError:
        return False
