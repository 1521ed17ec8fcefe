"""Options several commands share, declared once: their flag, their help and how they are read.

A command composes the ones it takes in ``add_parser`` (``add_blend(p)``, ``add_scene(p)``,
``add_resolution(p)`` ...) and reads the ones that need a check with the ``read_*`` functions in
``run``, so that every error names the flag the user typed and one option means one thing in
every command: ``--scene`` is always a scene of the .blend file (``apply`` takes the scene
description as ``--description``, ``demo`` its sample scene as ``--sample``), ``--resolution``
is always a render size WIDTHxHEIGHT read by one parser, ``--methods`` always techniques of the
registry.

``add_existing(p, what)`` adds ``--overwrite`` / ``--skip-existing`` (mutually exclusive);
``add_render_device(p)`` adds ``--threads`` / ``--device``; ``render_device(args, scene)`` is a
context manager that applies them to the scene for the command's work and puts it back after.
"""

from __future__ import annotations

import contextlib

#: Cycles devices --device accepts (``blender.device.DEVICES``, repeated here so that the parser
#: is built without bpy; a test holds them equal).
DEVICES = ("CPU", "CUDA", "OPTIX", "HIP", "ONEAPI", "METAL")


def add_blend(p, help: str = "the .blend file to read (never written)") -> None:
    p.add_argument("blend", help=help)


def add_blend_to_blend(p, out_help: str) -> None:
    """The .blend to read, ``--out`` the .blend to write and ``--overwrite``, for commands that
    change a scene and save it as a new file; check them with ``read_blend_out``."""
    add_blend(p, help="the .blend file to read (written only when it is OUT and --overwrite is given)")
    p.add_argument("--out", required=True, help=out_help)
    p.add_argument("--overwrite", action="store_true", help="allow OUT to be an existing file, the input included")


def read_blend_out(args) -> str:
    """The absolute path of ``--out``: a .blend file name that is not a folder and, without
    ``--overwrite``, no existing file (the input least of all)."""
    import os

    from .cli import CommandError

    blend, out = args.blend, args.out
    if not out.endswith(".blend"):
        raise CommandError(f"--out {out!r}: expected a .blend file name")
    out_abs = os.path.abspath(out)
    if os.path.exists(out_abs) and not args.overwrite:
        same = os.path.exists(blend) and os.path.samefile(blend, out_abs)
        what = "is the input file" if same else "exists"
        raise CommandError(f"--out {out!r} {what}; refusing to overwrite it (pass --overwrite to allow it)")
    if os.path.isdir(out_abs):
        raise CommandError(f"--out {out!r} is a folder; expected a .blend file name")
    return out_abs


def add_scene(p) -> None:
    """``--scene NAME``: a scene of the .blend file, the one meaning of --scene."""
    p.add_argument("--scene", metavar="NAME", help="scene of the .blend file (default: the file's active scene)")


def add_resolution(p, help: str = "render size WIDTHxHEIGHT at 100%% (default: the scene's)") -> None:
    """``--resolution WxH``; read it with ``read_resolution``."""
    p.add_argument("--resolution", metavar="WxH", help=help)


def read_resolution(args) -> tuple[int, int] | None:
    """``--resolution`` as (width, height), None when not given; CommandError naming the flag."""
    from ..core.scene.scene import parse_resolution
    from .cli import CommandError

    if args.resolution is None:
        return None
    try:
        return parse_resolution(args.resolution)
    except ValueError as exc:
        raise CommandError(f"--resolution: {exc}") from None


def add_samples(p, flag: str = "--samples", *, default: int | None = None, help: str, old: str | None = None) -> None:
    """A sample count (``--samples``, ``--pass-samples`` ...); check it with ``check_at_least``.
    ``old``: an earlier spelling still taken, deprecated (``deprecated_alias``)."""
    if old is None:
        p.add_argument(flag, type=int, default=default, metavar="N", help=help)
    else:
        p.add_argument(flag, old, type=int, default=default, metavar="N", help=help, action=deprecated_alias(old))


def add_seed(p, *, default: int | None = None, help: str = "Cycles seed (default: the scene's)") -> None:
    p.add_argument("--seed", type=int, default=default, help=help)


def add_frames(p, help: str = "frames, e.g. 1-10, 1-3,7 or 1-9:2 (default: the scene's current frame)") -> None:
    p.add_argument("--frames", help=help)


def add_one_frame(p, what: str) -> None:
    """``--frames N`` for a command that takes one frame (``what`` it does with it): the one name
    every command gives frames; a range is refused, and the old ``--frame`` still works with a note."""
    import argparse
    import sys

    class OneFrame(argparse.Action):
        def __call__(self, parser, namespace, values, option_string=None):
            if option_string == "--frame":
                print("sss_lab: note: --frame is deprecated; use --frames", file=sys.stderr)
            try:
                frame = int(str(values).strip())
            except ValueError:
                parser.error(f"--frames {values!r}: {what} one frame; give one, e.g. --frames 3")
            setattr(namespace, self.dest, frame)

    p.add_argument(
        "--frames",
        "--frame",
        dest="frame",
        metavar="N",
        action=OneFrame,
        help=f"the frame to {what} (one frame; default: the scene's current frame)",
    )


def add_view_layer(p, help: str) -> None:
    p.add_argument("--view-layer", metavar="NAME", help=help)


def deprecated_alias(old: str):
    """An argparse action for an option that also answers to an ``old`` spelling: the old one
    still works and says, on stderr, which to use (one name per concept across the commands)."""
    import argparse
    import sys

    class Alias(argparse.Action):
        def __call__(self, parser, namespace, values, option_string=None):
            if option_string == old:
                print(f"sss_lab: note: {old} is deprecated; use {self.option_strings[0]}", file=sys.stderr)
            setattr(namespace, self.dest, values)

    return Alias


def add_methods(p, *, default: str = "all", what: str = "techniques") -> None:
    """``--methods``: techniques of the registry, a comma-separated list, or all (read with
    ``cli.parse_methods``)."""
    from ..core.techniques.registry import TECHNIQUES

    p.add_argument(
        "--methods",
        default=default,
        help=f"{what}: {', '.join(TECHNIQUES)}, a comma-separated list, or all (default: {default})",
    )


def check_at_least(args, minimum: int, *names: str) -> None:
    """Each integer option ``names`` (attribute names) that is given is at least ``minimum``;
    CommandError naming the flag otherwise."""
    from .cli import CommandError

    for name in names:
        value = getattr(args, name)
        if value is not None and value < minimum:
            raise CommandError(f"--{name.replace('_', '-')}: expected an integer >= {minimum}, got {value}")


def add_existing(p, what: str) -> None:
    """``--overwrite`` and ``--skip-existing`` for the files the command writes (``what``)."""
    group = p.add_mutually_exclusive_group()
    group.add_argument("--overwrite", action="store_true", help=f"replace {what} that already exist")
    group.add_argument(
        "--skip-existing",
        action="store_true",
        help=f"keep {what} that already exist and do only the rest (resume a farm chunk); says what it skipped",
    )


def _threads(text: str) -> int:
    import argparse

    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 1024:
        raise argparse.ArgumentTypeError(f"expected an integer from 0 (one per core) to 1024, got {text!r}")
    return value


def add_render_device(p) -> None:
    """``--threads`` and ``--device`` for a command that renders with Blender."""
    p.add_argument(
        "--threads", type=_threads, metavar="N", help="render threads, 0 for one per core (default: the scene's)"
    )
    p.add_argument(
        "--device",
        type=str.upper,
        choices=DEVICES,
        help="Cycles device: CPU or a GPU back-end (default: the scene's and the preferences')",
    )


@contextlib.contextmanager
def render_device(args, scene, log=print):
    """Apply ``--threads``/``--device`` to ``scene`` for the block, then put everything back."""
    from ..blender.device import set_threads_and_device
    from ..blender.state import SceneState

    with SceneState() as state:
        said = set_threads_and_device(state, scene, threads=args.threads, device=args.device)
        if said and log is not None:
            log(said)
        yield


def _save_copy(path: str) -> None:
    """Blender's save of the open file as a copy at ``path`` (a seam the tests replace)."""
    import bpy

    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True, check_existing=False, relative_remap=True)


def _read_back(path: str) -> None:
    """Read the .blend file at ``path`` back (its list of scenes): OSError for a file Blender cannot
    open, RuntimeError for one without a scene. Nothing is linked into the open file."""
    import bpy

    before = set(bpy.data.libraries)
    with bpy.data.libraries.load(path) as (source, _):
        scenes = list(source.scenes)
    for library in set(bpy.data.libraries) - before:
        bpy.data.libraries.remove(library)
    if not scenes:
        raise RuntimeError("the written file holds no scene")


def save_blend(out: str, *, overwrite: bool = False) -> None:
    """Save the open file as a copy at ``out``: written under a temporary name beside it, read back
    by Blender, then moved into place; OutputError (and nothing at ``out``) when the write or the
    read-back fails, as on a full disk where Blender's saver leaves a truncated file and no error.
    ``out`` was checked by ``read_blend_out`` (existing only with ``--overwrite``); without
    ``overwrite`` the move never replaces a file, so of two runs started together with one --out
    the second to finish refuses (FileExistsError) instead of replacing the first's file."""
    import os

    from ..core.base import files

    with files.temporary_beside(out, suffix=".blend") as tmp:
        try:
            # Blender backs up a file it saves over (tmp + "1"): the placeholder goes first.
            os.remove(tmp)
            _save_copy(tmp)
            if os.path.lexists(tmp + "1"):
                os.remove(tmp + "1")
            if os.path.getsize(tmp) == 0:
                raise RuntimeError("Blender wrote an empty file")
            _read_back(tmp)
        except (OSError, RuntimeError) as exc:
            raise files.write_failure(out, exc) from None
        files.move_into_place(tmp, out, overwrite=overwrite)
