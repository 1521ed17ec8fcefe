"""Atomic file writing shared by the EXR, PNG and report writers (no Blender)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable


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
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=folder, prefix="." + os.path.basename(path) + ".", suffix=".tmp")
    os.close(fd)
    try:
        write(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        if overwrite:
            os.replace(tmp, path)
        else:
            _move_no_clobber(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    return path


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
