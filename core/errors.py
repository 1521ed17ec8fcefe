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
