"""Progress lines for long jobs on render farms: one line per event, elapsed time and ETA.

Farm logs are read line by line (no carriage-return bars), and farm managers pick up the files a
task wrote from Blender's own form ``Saved: '<path>'`` (``docs/references.md §10``): every
command of SSS Lab prints written files in that one form, through ``saved_line``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any, TextIO


def printable(text: str) -> str:
    """``text`` with every character that is not printable (a newline, a carriage return, an
    escape sequence's ESC, a backspace...) written as its Python escape (``\\n``, ``\\x1b``): a name
    read from a file can then neither start a log line of its own nor drive the terminal."""
    return _escaped(text)


def _escaped(text: str, keep: str = "") -> str:
    """``text`` with every character that is neither printable nor in ``keep`` escaped."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() or c in keep else c.encode("unicode_escape").decode("ascii") for c in text)


#: Every line ``saved_line`` made in this process: the only lines the guarded output
#: (``GuardedOutput``) lets begin with ``Saved:``.
_SAVED_LINES: set[str] = set()
#: The paths of those lines, in the order they were made (a command's ``--json`` summary lists them).
SAVED_PATHS: list[str] = []


def saved_line(path: str | os.PathLike[str]) -> str:
    """``Saved: '<absolute path>'``, the form Blender prints for every file it writes; a character
    of the path that is not printable is escaped (``printable``), so the line stays one line."""
    line = f"Saved: '{printable(os.path.abspath(os.fspath(path)))}'"
    if line not in _SAVED_LINES:
        SAVED_PATHS.append(os.path.abspath(os.fspath(path)))
    _SAVED_LINES.add(line)
    return line


def _keep_line_breaks(text: str) -> str:
    return _escaped(text, keep="\n\t")


class GuardedOutput:
    """A text stream in front of the command line's stdout or stderr that keeps names read from
    files from forging or driving anything, whichever message printed them: every character that
    is not printable but a line break or a tab is escaped (``printable``: an ESC, a carriage
    return, a bell), and a line that begins with ``Saved:`` but was not made by ``saved_line`` (a
    name holding a line break followed by a forged Saved line) is written with the escaped line
    break in front (``\\nSaved: ...``), so a farm manager never reads it as a file written."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream
        self._partial = ""
        self._line_start = True  # nothing of the current line written yet
        #: Every whole line written (escaped) once a command's ``--json`` summary asks for them
        #: (a list); None: not kept.
        self.lines: list[str] | None = None
        #: "info" writes every line; "warning" only lines that warn or note and the Saved lines;
        #: "error" only the Saved lines (the command line's --log-level and --quiet).
        self.level = "info"

    def _kept(self, line: str) -> bool:
        if self.level == "info" or line in _SAVED_LINES:
            return True
        low = line.lower()
        return self.level == "warning" and ("warning" in low or "note" in low or "error" in low)

    def write(self, text: str) -> int:
        self._partial += text
        *lines, self._partial = self._partial.split("\n")
        for line in lines:
            if self._line_start and not self._kept(line):
                continue
            shown = self._line(line)
            if self.lines is not None:
                self.lines.append(shown)
            self._stream.write(shown + "\n")
            self._line_start = True
        return len(text)

    def _line(self, line: str) -> str:
        if self._line_start and line.startswith("Saved:") and line not in _SAVED_LINES:
            line = "\\n" + line
        return _keep_line_breaks(line)

    def flush(self) -> None:
        if self._partial and self.level == "info":  # a line without its end yet (a prompt, a progress dot)
            self._stream.write(self._line(self._partial))
            self._partial = ""
            self._line_start = False
        self._stream.flush()

    def __getattr__(self, name: str) -> Any:  # fileno, isatty, encoding...: the stream's own
        return getattr(self._stream, name)


def format_seconds(seconds: float) -> str:
    """``4.2 s`` under a minute, ``3:07`` under an hour, ``1:02:03`` above."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    whole = round(seconds)
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class Progress:
    """Counts the items of a job (frames, seeds) as they finish or are skipped.

    The ETA is the mean time of the items done so far times the items left; skipped items
    (``--skip-existing``) take no time and count neither way, so a resumed chunk does not
    promise a too-early end.
    """

    def __init__(self, total: int, *, clock: Callable[[], float] = time.monotonic):
        if total < 0:
            raise ValueError(f"total: expected an integer >= 0, got {total!r}")
        self.total = total
        self.done = 0
        self.skipped = 0
        self._clock = clock
        self._start = clock()

    @property
    def elapsed(self) -> float:
        return self._clock() - self._start

    @property
    def eta(self) -> float | None:
        """Seconds left, or None before the first item has been done (nothing to go by)."""
        left = self.total - self.done - self.skipped
        if left <= 0:
            return 0.0
        if self.done == 0:
            return None
        return self.elapsed / self.done * left

    def position(self) -> str:
        """``[i/n]``: the item being worked on."""
        return f"[{min(self.done + self.skipped + 1, self.total)}/{self.total}]"

    def finish(self) -> str:
        """Count one item done; returns ``i/n, elapsed X, ETA Y``."""
        self.done += 1
        return self.status()

    def skip(self) -> str:
        self.skipped += 1
        return self.status()

    def status(self) -> str:
        eta = self.eta
        return (
            f"{self.done + self.skipped}/{self.total}, elapsed {format_seconds(self.elapsed)}, "
            f"ETA {'unknown' if eta is None else format_seconds(eta)}"
        )
