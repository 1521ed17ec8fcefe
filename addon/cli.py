"""SSS Lab's command line: ``python -m sss_lab COMMAND ...``.

Each command lives in its own module with ``add_parser(subparsers)`` and ``run(args) -> int``.
The modules must import without bpy: commands that need Blender import it inside ``run`` via
``require_bpy``, so that ``--help`` and the NumPy-only commands work on a render-farm node.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback

from ..core.base.errors import SSSLabError, describe_os_error, is_bad_input
from ..core.base.progress import GuardedOutput
from ..core.techniques.registry import TECHNIQUES, check_technique
from .interrupt import EXIT_INTERRUPTED, finished_summary, interrupt_guard, interrupted_by

#: Command modules, relative to this package, in the order ``--help`` lists them.
COMMANDS = (
    ".cli_scan",
    ".cli_demo",
    ".cli_apply",
    ".cli_bake",
    ".cli_render",
    ".cli_compare",
    ".cli_calibrate",
    ".cli_match_eevee",
    ".cli_export_profiles",
    ".cli_reference",
    ".cli_merge_reference",
    ".cli_prepare",
)


#: Exit status of the command line when no material of the scene scatters (nothing written).
EXIT_NOTHING_TO_DO = 3


def parse_methods(text: str, *, allow_auto: bool = False) -> list[str]:
    """``"burley"``, ``"sta,ssss"`` or ``"all"`` -> technique names; ValueError lists the known ones.
    With ``allow_auto`` (``apply``), ``"auto"`` alone: a technique chosen per material (``core/pipeline/auto.py``).
    ``all`` and ``auto`` stand alone: listed with another method they are refused, saying so."""
    alone = ("all", "auto") if allow_auto else ("all",)
    choices = f"{', '.join(TECHNIQUES)} (one or several, comma-separated), or {' or '.join(alone)} alone"
    names = list(dict.fromkeys(t.strip() for t in str(text).split(",") if t.strip()))
    if not names:
        raise ValueError(f"--methods: expected {choices}, got {text!r}")
    if names == ["all"]:
        return list(TECHNIQUES)
    if allow_auto and names == ["auto"]:
        return names
    for name in names:
        if name in alone:
            what = "runs every technique" if name == "all" else "chooses a technique per material"
            raise ValueError(
                f"--methods: {name!r} {what} and stands alone: it cannot be combined with other methods, got"
                f" {text!r}; give {name} alone, or the techniques wanted ({', '.join(TECHNIQUES)})"
            )
    out = []
    for name in names:
        try:
            check_technique(name)
        except ValueError:
            raise ValueError(f"--methods: unknown method {name!r}; expected {choices}") from None
        out.append(name)
    return out


class CommandError(SSSLabError):
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
    parser.add_argument("--version", action="version", version=f"SSS Lab {version()}")
    for name in COMMANDS:
        importlib.import_module(name, __package__).add_parser(sub)
    for p in (parser, *sub.choices.values()):  # before or after the command: sss_lab apply ... --debug
        _add_shared(p, suppress=p is not parser)
    for name, p in sub.choices.items():
        if not any("--json" in a.option_strings for a in p._actions):
            p.add_argument(
                "--json",
                metavar="FILE",
                help="also write a summary of the run (exit status, files written, lines printed) to this JSON file",
            )
            p.set_defaults(summary_json=True)
        own = EXIT_STATUS.get(name)
        p.epilog = (f"Exit status: {own}. " if own else "") + EXIT_COMMON
    return parser


#: Exit statuses of the commands whose description does not give them (the others say theirs).
EXIT_STATUS = {
    "scan": "0 the materials listed (or the recommendation made), 2 bad arguments or input",
    "demo": "0 the report complete, 1 the report incomplete (a technique could not run; the report says why),"
    " 2 bad arguments",
    "bake-thickness": "0 every object baked, 1 some failed (each named on one line), 2 bad arguments or input",
    "compare": "0 the report complete, 1 the report incomplete (a technique could not run; the report says why),"
    " 2 bad arguments or input (an earlier report in OUT without --overwrite included)",
    "reference": "0 the parts written (or kept with --skip-existing), 2 bad arguments or input",
    "merge-reference": "0 merged, 2 bad arguments or parts that are not of one render",
    "prepare": "0 every kernel ready, 2 bad arguments or a kernel that cannot be compiled here",
}
#: What every command shares, after its own statuses.
EXIT_COMMON = (
    "Every command: 1 when a file cannot be written (a full or read-only disk, no permission), 130 when"
    " interrupted (Ctrl-C, SIGTERM, SIGHUP); a path naming nothing, a folder where a file was meant (or the"
    " reverse), and an existing output without --overwrite are bad input, 2."
)


def version() -> str:
    """SSS Lab's version, from the extension's manifest."""
    import os
    import tomllib

    path = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "blender_manifest.toml")
    with open(path, "rb") as fh:
        return str(tomllib.load(fh)["version"])


#: --log-level's levels: what the command prints on stdout at each (errors always go to stderr).
LOG_LEVELS = {
    "info": "every progress line (the default)",
    "warning": "warnings and notes, and the Saved lines",
    "error": "the Saved lines only (as --quiet)",
}


def _add_shared(p, *, suppress: bool) -> None:
    """The options every command takes, before or after its name: --debug, --quiet, --log-level."""
    default = {"default": argparse.SUPPRESS} if suppress else {}
    p.add_argument(
        "--debug",
        action="store_true",
        help="on an error, show the Python traceback after the one-line message",
        **default,
    )
    p.add_argument(
        "--quiet", action="store_true", help="print only the Saved lines and errors (as --log-level error)", **default
    )
    p.add_argument(
        "--log-level",
        choices=tuple(LOG_LEVELS),
        help="what to print: " + "; ".join(f"{k}: {v}" for k, v in LOG_LEVELS.items()),
        **default,
    )


def _one_line(exc: BaseException) -> str:
    text = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
    if isinstance(exc, OSError) and not isinstance(exc, SSSLabError) and exc.strerror:
        text = describe_os_error(exc)
    return " ".join(text.split()) or type(exc).__name__


#: The options that name a file or folder: given empty, they are an error, not "the default".
_PATH_OPTIONS = ("out", "json", "cache", "description", "image_dir", "reference", "frames")


def _no_empty_paths(args) -> None:
    """CommandError for an option in ``_PATH_OPTIONS`` given as an empty string (``--out ''``,
    which a script building the command line from an unset variable produces): it named no file,
    and taking the default instead would write or read somewhere the user did not say."""
    for name in _PATH_OPTIONS:
        value = getattr(args, name, None)
        if isinstance(value, str) and not value.strip():
            flag = "--" + name.replace("_", "-")
            raise CommandError(f"{flag}: empty; expected a value (leave the option out for its default)")


def main(argv: list[str] | None = None, *, prog: str = "python -m sss_lab") -> int:
    """Run one command. Errors SSS Lab raises on purpose (``SSSLabError``), bad values and files,
    and the operating system's refusals (a full or read-only disk) end as one line on stderr
    with a non-zero exit: 2 for bad input, 1 for a failure to write or run, 130 for Ctrl-C.
    Anything else is a bug and keeps its traceback. ``--debug`` shows the traceback always."""
    argv = sys.argv[1:] if argv is None else list(argv)
    out, err = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = GuardedOutput(out), GuardedOutput(err)
    try:
        return _main(argv, prog)
    finally:
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        sys.stdout, sys.stderr = out, err


def _main(argv: list[str], prog: str) -> int:
    # The guard is on before anything is imported or parsed: a Ctrl-C at start-up is one too.
    command = next((a for a in argv if not a.startswith("-")), "")
    debug = "--debug" in argv
    summary: str | None = None
    error: str | None = None
    from ..core.base.progress import SAVED_PATHS

    SAVED_PATHS.clear()  # this run's files only (the tests run many in one process)
    try:
        with interrupt_guard(command):
            args = build_parser(prog).parse_args(argv)
            debug = getattr(args, "debug", False)
            level = "error" if getattr(args, "quiet", False) else (getattr(args, "log_level", None) or "info")
            if isinstance(sys.stdout, GuardedOutput):
                sys.stdout.level = level
            _no_empty_paths(args)
            summary = _summary_path(args)
            if summary is not None and isinstance(sys.stdout, GuardedOutput):
                sys.stdout.lines = []  # what the run prints goes into the summary
            code = int(args.run(args) or 0)
    except KeyboardInterrupt:
        if debug:
            traceback.print_exc()
        error = f"interrupted ({interrupted_by()}){finished_summary()}"
        print(f"sss_lab {command}: {error}", file=sys.stderr)
        code = EXIT_INTERRUPTED
    except (SSSLabError, ValueError, OSError) as exc:
        if debug:
            traceback.print_exc()
        error = _with_flag(_one_line(exc), argv)
        print(f"sss_lab {command}: error: {error}", file=sys.stderr)
        code = 2 if is_bad_input(exc) else 1
    if summary is not None:
        _write_summary(summary, command, argv, code, error)
    return code


#: Settings' field names that the command line spells otherwise (a message naming the field
#: names the flag the user typed instead).
_FIELD_FLAGS = {"techniques": "--methods", "resolution_px": "--image-size", "cycles_samples": "--samples"}


def _with_flag(message: str, argv: list[str]) -> str:
    """``message`` with a leading settings field (``max_error: expected ...``) named as the flag
    the user typed (``--max-error``), when that flag is on the command line."""
    field, sep, rest = message.partition(": ")
    if not sep or not field.isidentifier():
        return message
    flag = _FIELD_FLAGS.get(field, "--" + field.replace("_", "-"))
    given = {a.split("=", 1)[0] for a in argv if a.startswith("--")}
    return f"{flag}: {rest}" if flag in given else message


def json_out_path(args, protect: dict[str, str | None]) -> str | None:
    """The absolute path of ``--json``, checked before anything runs: a .json file name that is
    none of the files in ``protect`` (what it is -> path, e.g. ``{"the input .blend": ...}``; links
    resolved) and, without ``--overwrite``, no existing file; None without ``--json``."""
    import os

    if not args.json:
        return None
    path = os.path.abspath(args.json)
    if not path.endswith(".json"):
        raise CommandError(f"--json {args.json!r}: expected a .json file name")
    if os.path.isdir(path):
        raise CommandError(f"--json {args.json!r} is a folder; expected a .json file name")
    real = os.path.realpath(path)
    for label, other in protect.items():
        if other and real == os.path.realpath(os.path.abspath(other)):
            raise CommandError(f"--json {args.json!r} is {label}; refusing to write over it")
    if os.path.exists(path) and not getattr(args, "overwrite", False):
        raise CommandError(f"--json {args.json!r} exists; refusing to overwrite it (pass --overwrite to allow it)")
    return path


def _summary_path(args) -> str | None:
    """The ``--json`` summary's path, checked before the command runs like every ``--json``
    (commands with a ``--json`` of their own check theirs)."""
    if not getattr(args, "summary_json", False):
        return None
    inputs = {name: getattr(args, name, None) for name in ("blend", "passes", "description", "reference")}
    inputs.update({f"part {i + 1}": part for i, part in enumerate(getattr(args, "parts", None) or [])})
    return json_out_path(args, {f"an input ({k})": v for k, v in inputs.items() if isinstance(v, str)})


def _write_summary(path: str, command: str, argv: list[str], code: int, error: str | None) -> None:
    """The run as data: the command, its exit status and error, the files it wrote, what it printed."""
    import json

    from ..core.base import files
    from ..core.base.progress import SAVED_PATHS, saved_line

    printed = list(sys.stdout.lines or []) if isinstance(sys.stdout, GuardedOutput) else []
    data = {
        "command": command,
        "argv": argv,
        "exit_status": code,
        "error": error,
        "saved": list(SAVED_PATHS),
        "printed": printed,
    }
    try:
        files.write_text(path, json.dumps(data, indent=2))
    except OSError as exc:
        print(f"sss_lab {command}: error: {_one_line(exc)}", file=sys.stderr)
        return
    print(saved_line(path), flush=True)


def script() -> int:
    """The ``sss-lab`` console script (pyproject.toml): ``main`` with its own name in the usage."""
    return main(prog="sss-lab")


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
