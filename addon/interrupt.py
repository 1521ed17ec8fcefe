"""Ctrl-C for the command line: stop within seconds, exit 130, keep finished files, leave no
temporary file.

Python runs its SIGINT handler only in the main thread, between bytecodes. That is enough
between renders: the KeyboardInterrupt unwinds, the operators' ``finally`` blocks put the
scene back, and the entry point prints one line. During a Cycles render or bake the main
thread sits in Blender's C code for as long as the render lasts; the interrupt, when Python
finally sees it, is raised inside Cycles' own Python callback, where Blender catches and
prints it, and the job ran to the end with exit 0.

So the guard also watches from a second thread: the C-level part of Python's handler writes
each signal's number to a pipe (``signal.set_wakeup_fd``) at once, whatever the main thread
does. When SIGINT arrives the watcher gives the main thread ``GRACE_SECONDS`` to unwind by
itself; if it has not finished by then (it is inside a render), the watcher removes the
temporary files being written (``core.base.files``), says which files were finished, and ends
the process with status 130. Nothing on disk needs putting back at that point: inputs are
never written, and every output is moved into place whole or not at all.

Blender catches a KeyboardInterrupt raised inside its render and bake callbacks, and the job
may then go on with a cut-short result. So once SIGINT has arrived no output is moved into
place any more (``core.base.files.INTERRUPTED``), and a job that finishes anyway exits 130.

SIGTERM and SIGHUP (a farm manager cancelling a task, a closed terminal) stop a command exactly as
Ctrl-C does, and the messages name the signal.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import os
import signal
import sys
import threading

from ..core.base import files

#: Seconds the main thread gets to unwind after Ctrl-C before the process is ended for it.
GRACE_SECONDS = 2.0
#: Exit status after Ctrl-C (128 + SIGINT), as shells report it; also after SIGTERM and SIGHUP,
#: which stop a command the same way (a farm manager cancelling a task, a closed terminal).
EXIT_INTERRUPTED = 130
#: The signals that interrupt a command: Ctrl-C, and where the platform has them a polite kill
#: and a hang-up.
SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


#: How the last interrupt arrived, for the messages: "Ctrl-C", "SIGTERM" or "SIGHUP".
_RECEIVED = ["Ctrl-C"]


def _name(signum: int) -> str:
    return "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name


def interrupted_by() -> str:
    """ "Ctrl-C", or the name of the signal that interrupted the command."""
    return _RECEIVED[0]


def finished_summary() -> str:
    """'; N file(s) finished and kept (the last: PATH)' or '' when none was."""
    done = files.FINISHED
    if not done:
        return "; no file was finished"
    return f"; {len(done)} file(s) finished and kept (the last: {done[-1]})"


def _force_exit(command: str) -> None:
    files.remove_pending_temporaries()
    try:
        sys.stdout.flush()
    except (OSError, ValueError):
        pass
    message = (
        f"sss_lab {command}: interrupted ({interrupted_by()}) while Blender was busy (starting, rendering or baking): "
        f"stopped{finished_summary()}; no partial file left\n"
    )
    try:
        os.write(2, message.encode("utf-8", "replace"))
    finally:
        os._exit(EXIT_INTERRUPTED)


@functools.cache
def _blender_scripts() -> tuple[str, ...]:
    """Folders of the Python code that Blender itself runs and calls back (its start-up scripts,
    Cycles' render engine); empty without Blender. Found without importing bpy, so that it is
    known before the command imports it."""
    bpy = sys.modules.get("bpy")
    if bpy is not None and hasattr(bpy, "utils"):  # inside Blender, or bpy already imported
        folders = [bpy.utils.system_resource("SCRIPTS"), bpy.utils.user_resource("SCRIPTS")]
    else:  # the bpy module from the package index keeps its scripts inside its package folder
        try:
            spec = importlib.util.find_spec("bpy")
        except (ImportError, ValueError):
            spec = None
        folders = list(spec.submodule_search_locations or ()) if spec else []
    return tuple(os.path.join(os.path.abspath(f), "") for f in folders if f)


def _handler(signum, frame) -> None:
    """Python's default SIGINT behaviour (KeyboardInterrupt), except inside one of Blender's own
    Python callbacks: Blender prints an exception raised there as a traceback and carries on, so
    there the interrupt is left to the watcher, which ends the process within the grace period."""
    _RECEIVED[0] = _name(signum)
    scripts = _blender_scripts()
    while frame is not None:  # the whole stack: Blender may be importing or calling its scripts
        name = frame.f_code.co_filename
        # An import in progress is no place either: an exception inside bpy's start-up (its C
        # code runs Python through the import machinery) crashes Blender.
        if name.startswith("<frozen importlib") or os.path.abspath(name).startswith(scripts):
            return
        frame = frame.f_back
    raise KeyboardInterrupt


@contextlib.contextmanager
def interrupt_guard(command: str, grace: float = GRACE_SECONDS):
    """Within the block, Ctrl-C (or SIGTERM, SIGHUP: ``SIGNALS``) raises KeyboardInterrupt in the
    main thread as Ctrl-C does, and ends
    the process with status 130 when the main thread does not get back to Python within
    ``grace`` seconds. Does nothing outside the main thread (signals go to the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _blender_scripts()  # known before the first signal: the handler only compares strings
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)
    previous_handlers = {s: signal.signal(s, _handler) for s in SIGNALS}
    try:
        previous_fd = signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    except ValueError:  # not the main interpreter
        for s, h in previous_handlers.items():
            signal.signal(s, h)
        os.close(read_fd)
        os.close(write_fd)
        yield
        return
    done = threading.Event()

    def watch():
        while True:
            try:
                data = os.read(read_fd, 64)
            except OSError:
                return
            if done.is_set() or not data:
                return
            arrived = [s for s in SIGNALS if s in data]
            if arrived:
                _RECEIVED[0] = _name(arrived[-1])
                files.INTERRUPTED.set()
                if not done.wait(grace):
                    _force_exit(command)

    watcher = threading.Thread(target=watch, name="sss_lab-interrupt", daemon=True)
    files.INTERRUPTED.clear()
    _RECEIVED[0] = "Ctrl-C"
    watcher.start()
    try:
        yield
        # Blender may have swallowed the KeyboardInterrupt (raised inside its render or bake
        # callback) and let the job finish on a cut-short result: it is not a success.
        files.check_interrupted()
    finally:
        done.set()
        signal.set_wakeup_fd(previous_fd)
        for s, h in previous_handlers.items():
            signal.signal(s, h)
        os.write(write_fd, b"\0")  # wake the watcher so that it ends
        watcher.join(timeout=1.0)
        os.close(write_fd)
        os.close(read_fd)
