"""SSS Lab's command line: ``python -m sss_lab COMMAND ...``.

Each command lives in its own module with ``add_parser(subparsers)`` and ``run(args) -> int``.
The modules must import without bpy: commands that need Blender import it inside ``run`` via
``require_bpy``, so that ``--help`` and the NumPy-only commands work on a render-farm node.
"""

from __future__ import annotations

import argparse
import importlib
import sys

#: Command modules, relative to this package, in the order ``--help`` lists them.
COMMANDS = (
    ".cli_scan",
    ".cli_demo",
    ".cli_apply",
    ".cli_bake",
    ".cli_render",
    ".cli_compare",
    ".cli_calibrate",
)


class CommandError(Exception):
    """A failure to report as one clear line (no traceback), with exit status 2."""


def require_bpy():
    """Import bpy, or raise CommandError saying how to get it."""
    try:
        import bpy
    except ImportError:
        raise CommandError(
            "this command needs Blender's Python module: install it with "
            "`pip install bpy==5.2.3` into a Python 3.13 environment (`make demo` sets one up in .venv), "
            "or run it inside Blender"
        ) from None
    return bpy


def build_parser(prog: str = "python -m sss_lab") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        description="SSS Lab: real-time subsurface scattering approximations, measured against Cycles.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(name, __package__).add_parser(sub)
    return parser


def main(argv: list[str] | None = None, *, prog: str = "python -m sss_lab") -> int:
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except CommandError as exc:
        print(f"sss_lab {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except (ValueError, FileNotFoundError, FileExistsError) as exc:
        print(f"sss_lab {args.command}: error: {exc}", file=sys.stderr)
        return 2


#: The id of the command the extension registers with Blender: ``blender --command sss_lab ...``.
BLENDER_COMMAND = "sss_lab"


def blender_command(argv: list[str]) -> int:
    """``blender --command sss_lab COMMAND ...``: the same commands inside Blender (registered by
    the extension with ``bpy.utils.register_cli_command``), for render-farm nodes that have Blender
    but not the bpy module. argparse's exits (``--help``, a usage error) become return codes."""
    try:
        return main(list(argv), prog=f"blender --command {BLENDER_COMMAND}")
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
