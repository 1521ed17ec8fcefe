"""The project's error classes: one base, so that callers catch SSS Lab's errors in one place.

Every error raised on purpose by SSS Lab (bad input, a missing pass, a failed bake) derives from
``SSSLabError``. The command line turns an ``SSSLabError`` into one line on stderr and a non-zero
exit; anything else is a bug and keeps its traceback. Subclasses also derive from the built-in
exception a caller would expect (``ValueError`` for a bad value, ``KeyError`` for a missing pass,
``OSError`` for an unreadable file), so existing ``except ValueError`` code keeps working.
"""

from __future__ import annotations


class SSSLabError(Exception):
    """Base class of every error SSS Lab raises on purpose."""


class InputError(SSSLabError, ValueError):
    """A value, file or scene the user gave is not what was expected; the message says which."""


class DamagedFileError(InputError):
    """A file exists but cannot be read completely: truncated, damaged, or not of the expected
    format. The message names the file, the part that failed and what to do."""


class OutputError(SSSLabError, OSError):
    """An output could not be written (a full or read-only disk, no permission); the message
    names the file and what to do. Nothing partial is left under the output's name."""

    def __str__(self) -> str:  # OSError would prefix "[Errno N]"
        return self.strerror or super().__str__()


#: Operating-system errors that mean the user named the wrong thing (no such file, a folder where a
#: file was meant or the reverse, an existing output), not that a write failed.
BAD_PATH_ERRORS = (FileNotFoundError, IsADirectoryError, NotADirectoryError, FileExistsError)


def is_bad_input(exc: BaseException) -> bool:
    """True when ``exc`` means bad input (exit status 2), False when a write or the machine failed
    (exit status 1): the command line's one rule, for every subcommand. A value or a file that is
    not what was expected, a missing pass, a path naming nothing or the wrong kind of thing are bad
    input; any other operating-system error (a full or read-only disk, no permission) is a failed
    write."""
    if isinstance(exc, BAD_PATH_ERRORS):
        return True
    if isinstance(exc, OSError):
        return False
    return isinstance(exc, (SSSLabError, ValueError, KeyError))


def describe_os_error(exc: OSError, path: str | None = None) -> str:
    """One line for an operating-system error on ``path``: the file, the cause, what to do."""
    import errno

    where = path or exc.filename or ""
    cause = exc.strerror or str(exc)
    hints = {
        errno.ENOSPC: "the disk is full: free some space (or write elsewhere with --out) and run again",
        errno.EDQUOT: "the disk quota is used up: free some space (or write elsewhere with --out) and run again",
        errno.EROFS: "the file system is read-only: write elsewhere with --out",
        errno.EACCES: "no permission to write there: write elsewhere with --out",
        errno.EPERM: "no permission to write there: write elsewhere with --out",
    }
    hint = hints.get(exc.errno) if exc.errno is not None else None
    text = f"{where}: {cause}" if where else cause
    return f"{text}; {hint}" if hint else text
