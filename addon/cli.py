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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m sss_lab",
        description="SSS Lab: real-time subsurface scattering approximations, measured against Cycles.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(name, __package__).add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except CommandError as exc:
        print(f"sss_lab {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except (ValueError, FileNotFoundError, FileExistsError) as exc:
        print(f"sss_lab {args.command}: error: {exc}", file=sys.stderr)
        return 2
