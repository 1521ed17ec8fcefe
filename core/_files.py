"""Atomic file writing shared by the EXR, PNG and report writers (no Blender)."""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from collections.abc import Callable

from .errors import OutputError, describe_os_error


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
    folder = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(folder, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix="." + os.path.basename(path) + ".", suffix=".tmp")
    except OSError as exc:
        raise OutputError(exc.errno, describe_os_error(exc, path)) from None
    os.close(fd)
    try:
        try:
            write(tmp)
        except RuntimeError as exc:
            # OpenEXR reports a failed write (a full disk among others) as a RuntimeError.
            raise _write_failure(path, folder, exc) from None
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        if overwrite:
            os.replace(tmp, path)
        else:
            _move_no_clobber(tmp, path)
    except FileExistsError:
        _remove(tmp)
        raise
    except OutputError:
        _remove(tmp)
        raise
    except OSError as exc:
        _remove(tmp)
        raise OutputError(exc.errno, describe_os_error(exc, path)) from None
    except BaseException:
        _remove(tmp)
        raise
    return path


def _remove(tmp: str) -> None:
    try:
        os.remove(tmp)
    except FileNotFoundError:
        pass


def _write_failure(path: str, folder: str, exc: RuntimeError) -> OutputError:
    """The error for a writer that failed without an errno: a full disk is the usual cause."""
    try:
        full = shutil.disk_usage(folder).free < 1 << 20
    except OSError:
        full = False
    if full:
        return OutputError(errno.ENOSPC, describe_os_error(OSError(errno.ENOSPC, "No space left on device"), path))
    return OutputError(errno.EIO, f"{path}: could not be written ({exc}); nothing was left under its name")


def open_for_writing_check(folder: str) -> None:
    """Raise OutputError at once when ``folder`` cannot be written to (read-only, no permission):
    before a long computation rather than after it."""
    probe = os.path.join(folder, ".sss_lab_write_test")
    try:
        fd = os.open(probe, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600)
    except FileExistsError:
        return
    except OSError as exc:
        raise OutputError(exc.errno, describe_os_error(exc, folder)) from None
    os.close(fd)
    os.remove(probe)


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
