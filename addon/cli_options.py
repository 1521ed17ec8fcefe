"""Options several commands share, declared once: what to do with existing outputs, and the
render threads and Cycles device of the commands that render with Blender (farm options).

``add_existing(p, what)`` adds ``--overwrite`` / ``--skip-existing`` (mutually exclusive);
``add_render_device(p)`` adds ``--threads`` / ``--device``; ``render_device(args, scene)`` is a
context manager that applies them to the scene for the command's work and puts it back after.
"""

from __future__ import annotations

import contextlib

#: Cycles devices --device accepts (``blender.device.DEVICES``, repeated here so that the parser
#: is built without bpy; a test holds them equal).
DEVICES = ("CPU", "CUDA", "OPTIX", "HIP", "ONEAPI", "METAL")


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
