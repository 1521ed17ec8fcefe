"""Atomic file writing shared by the EXR, PNG and report writers (no Blender)."""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import socket
import tempfile
import threading
from collections.abc import Callable

from .errors import OutputError, describe_os_error

#: Temporary files being written now; removed on failure, and by an interrupt that has to end
#: the process at once (``addon/interrupt.py``), so that none survives.
_PENDING: set[str] = set()
#: Files this process finished writing, in order: reported after an interrupt.
FINISHED: list[str] = []


#: Set when the user interrupted the process (``addon/interrupt.py``). From then on no output is
#: moved into place: Blender catches a KeyboardInterrupt raised inside its render and bake
#: callbacks and may go on with a cut-short result, which must not be published as finished.
INTERRUPTED = threading.Event()


def check_interrupted() -> None:
    """Raise KeyboardInterrupt if the user interrupted the process."""
    if INTERRUPTED.is_set():
        raise KeyboardInterrupt("interrupted (Ctrl-C) before this file was finished")


def pending_temporaries() -> list[str]:
    return sorted(_PENDING)


def remove_pending_temporaries() -> None:
    for tmp in list(_PENDING):
        _remove(tmp)
        _PENDING.discard(tmp)


def _owner() -> str:
    """This process as temporaries name it: host and process id (``host-pid``), the host reduced
    to letters, digits and hyphens."""
    host = "".join(c if c.isalnum() or c == "-" else "-" for c in socket.gethostname())[:64] or "host"
    return f"{host}-{os.getpid()}"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def remove_stale_temporaries(path: str, prefix: str | None = None) -> list[str]:
    """Remove the temporaries of ``path`` (``temporary_beside``'s names, or names starting with
    ``prefix`` in ``path``'s folder: ``temporary_folder``'s) that a process of this host left when
    it was killed without a chance to clean up (SIGKILL, a power cut): those whose process is gone.
    A temporary of a live process, or of another host sharing the folder, is kept. Returns the
    paths removed."""
    folder = os.path.dirname(os.path.abspath(path)) if prefix is None else os.path.abspath(path)
    start = ("." + os.path.basename(path) + ".") if prefix is None else prefix
    host = _owner().rsplit("-", 1)[0]
    removed: list[str] = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        if not name.startswith(start + host + "-"):
            continue
        pid_text = name[len(start + host + "-") :].split(".", 1)[0].split("_", 1)[0]
        if not pid_text.isdigit() or _alive(int(pid_text)) or int(pid_text) == os.getpid():
            continue
        target = os.path.join(folder, name)
        try:
            if os.path.isdir(target) and not os.path.islink(target):
                shutil.rmtree(target)
            else:
                os.remove(target)
            removed.append(target)
        except OSError:
            pass
    return removed


@contextlib.contextmanager
def temporary_beside(path: str, suffix: str = ".tmp"):
    """A temporary file name beside ``path`` (same file system, so a move is atomic), removed
    when the block fails; the block moves it into place itself. For writers that need to
    choose the name (Blender's image and render savers keep the extension: pass it in
    ``suffix``). The name carries this host and process id, so that the next writer of ``path``
    removes what a killed process left (``remove_stale_temporaries``)."""
    folder = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(folder, exist_ok=True)
        remove_stale_temporaries(path)
        fd, tmp = tempfile.mkstemp(
            dir=folder, prefix="." + os.path.basename(path) + "." + _owner() + ".", suffix=suffix
        )
    except OSError as exc:
        raise OutputError(exc.errno, describe_os_error(exc, path)) from None
    os.close(fd)
    _PENDING.add(tmp)
    try:
        yield tmp
    except BaseException:
        _remove(tmp)
        raise
    finally:
        _PENDING.discard(tmp)
    if os.path.exists(path):
        FINISHED.append(path)


def _move_no_clobber(tmp: str, path: str) -> None:
    """Move ``tmp`` to ``path`` atomically, failing if ``path`` appeared meanwhile.

    A hard link fails with FileExistsError when the target exists, which ``os.replace`` would
    silently overwrite; where the file system has no hard links, fall back to ``os.replace``.
    """
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise FileExistsError(f"{path} already exists; refusing to overwrite it (choose another output name)") from None
    except OSError:
        os.replace(tmp, path)
        return
    os.remove(tmp)


def atomic_write(path: str, write: Callable[[str], None], *, overwrite: bool = True) -> str:
    """Write ``path`` through ``write(temporary_path)``, then move the finished file into place.

    The temporary file sits beside ``path`` (same file system, so the move is atomic) and gets
    the usual permissions (mkstemp creates it 0600). With ``overwrite`` False an existing
    ``path`` is never replaced. On any failure no partial file is left behind.
    """
    path = os.fspath(path)
    if (os.path.lexists(path) and not os.path.isfile(path)) or os.path.isdir(path):
        kind = "a folder" if os.path.isdir(path) else "not a regular file (a device, pipe or dangling link)"
        raise FileExistsError(f"{path} is {kind}; refusing to write over it (choose a file name)")
    with temporary_beside(path) as tmp:
        _write_and_move(tmp, path, write, overwrite)
    return path


def _write_and_move(tmp: str, path: str, write: Callable[[str], None], overwrite: bool) -> None:
    """Write ``tmp`` and move it to ``path``; the caller removes ``tmp`` on failure."""
    try:
        write(tmp)
    except RuntimeError as exc:
        # OpenEXR reports a failed write (a full disk among others) as a RuntimeError.
        raise write_failure(path, exc) from None
    except (FileExistsError, OutputError):
        raise
    except OSError as exc:
        raise OutputError(exc.errno, describe_os_error(exc, path)) from None
    move_into_place(tmp, path, overwrite=overwrite)


def move_into_place(tmp: str, path: str, *, overwrite: bool = True) -> None:
    """Give the finished temporary file ``tmp`` the usual permissions (mkstemp makes it 0600) and
    move it to ``path`` atomically (never over an existing ``path`` unless ``overwrite``)."""
    check_interrupted()
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        if overwrite:
            os.replace(tmp, path)
        else:
            _move_no_clobber(tmp, path)
    except FileExistsError:
        raise
    except OSError as exc:
        raise OutputError(exc.errno, describe_os_error(exc, path)) from None


def _remove(tmp: str) -> None:
    """Remove a pending temporary: a file, or a folder (``temporary_folder``) with what it holds."""
    if os.path.isdir(tmp) and not os.path.islink(tmp):
        shutil.rmtree(tmp, ignore_errors=True)
        return
    try:
        os.remove(tmp)
    except FileNotFoundError:
        pass


def disk_full(path: str) -> bool:
    """True when the file system of ``path`` (a file or folder) has less than 1 MiB free."""
    folder = path if os.path.isdir(path) else os.path.dirname(os.path.abspath(path))
    try:
        return shutil.disk_usage(folder).free < 1 << 20
    except OSError:
        return False


def write_failure(path: str, exc: Exception) -> OutputError:
    """The error for a writer that failed without an errno (OpenEXR, Blender's image savers):
    a full disk is the usual cause, and is said so."""
    if disk_full(path):
        return OutputError(errno.ENOSPC, describe_os_error(OSError(errno.ENOSPC, "No space left on device"), path))
    return OutputError(errno.EIO, f"{path}: could not be written ({exc}); nothing was left under its name")


def write_bytes(path: str, data: bytes) -> str:
    def write(tmp):
        with open(tmp, "wb") as fh:
            fh.write(data)

    return atomic_write(path, write)


def write_text(path: str, text: str) -> str:
    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    return atomic_write(path, write)


def not_a_folder(path: str) -> str | None:
    """The first of ``path`` and the folders above it that exists but is not a folder (a file, a
    broken link): ``path`` can then be neither used nor made as a folder. None when it can."""
    here = os.path.abspath(path)
    while not os.path.isdir(here):
        if os.path.lexists(here):
            return here
        parent = os.path.dirname(here)
        if parent == here:
            return None
        here = parent
    return None


@contextlib.contextmanager
def temporary_folder(prefix: str):
    """A temporary folder in the system's temporary directory, removed at the end of the block;
    its name carries this host and process id (``prefix`` + ``host-pid_``), so that a later run
    removes the folders of runs that were killed (``remove_stale_temporaries``)."""
    base = tempfile.gettempdir()
    remove_stale_temporaries(base, prefix=prefix)
    folder = tempfile.mkdtemp(prefix=f"{prefix}{_owner()}_", dir=base)
    # Pending like a temporary file: an interrupt that ends the process at once (while Blender is
    # busy) removes it too, not only the end of this block.
    _PENDING.add(folder)
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)
        _PENDING.discard(folder)
