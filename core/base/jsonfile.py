"""Reading the JSON files a user hands over or leaves on disk (scene descriptions, the sidecars of
renders, reference parts and baked images, reports, the auto model): one reader for all of them.

Python's ``json`` fails on such a file in more ways than ``JSONDecodeError``: arrays or objects
nested some ten thousand levels deep raise ``RecursionError``, and a number of more than 4300
digits a ValueError that talks of ``sys.set_int_max_str_digits``. Nesting less deep still reads,
but then breaks whatever recurses over the value later (``repr`` in an error message,
``dataclasses.asdict``, ``copy.deepcopy``): the files SSS Lab reads nest a few levels, so more
than ``MAX_DEPTH`` is refused here too. Each way ends as one ``InputError`` (a ValueError) naming
the file and what it is not, so that no caller shows a traceback or Python's words for a file that
is simply not what was expected.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from typing import Any

from .errors import InputError

#: Arrays and objects within each other that a JSON file SSS Lab reads may hold (its own nest
#: five levels at most: a report's entries, a scene description's materials and their fits).
MAX_DEPTH = 100


def _depth_over(value, limit: int) -> bool:
    """True when ``value`` nests arrays or objects more than ``limit`` levels deep (walked without
    recursion)."""
    stack = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, (dict, list)):
            if depth > limit:
                return True
            stack.extend((child, depth + 1) for child in (item.values() if isinstance(item, dict) else item))
    return False


def parse_json(text: str | bytes, where: str, what: str, *, parse_constant: Callable[[str], Any] | None = None):
    """``json.loads(text)``; InputError starting with ``where`` (a file, or what the text is) for
    text that is not JSON, nests more than ``MAX_DEPTH`` levels or holds a number too long to read; ``what``
    (``"a scene description"``) is what the text was expected to be. A ValueError raised by
    ``parse_constant`` (NaN, Infinity) is passed on as it is."""
    too_deep = f"{where}: arrays or objects nested more than {MAX_DEPTH} levels deep; not {what}"
    try:
        data = json.loads(text, parse_constant=parse_constant)
    except json.JSONDecodeError as exc:
        raise InputError(f"{where}: not readable JSON ({exc}); expected {what}") from None
    except RecursionError:
        raise InputError(too_deep) from None
    except ValueError as exc:
        if "integer string conversion" not in str(exc):
            raise
        raise InputError(f"{where}: a number of more than 4300 digits; not {what}") from None
    if _depth_over(data, MAX_DEPTH):
        raise InputError(too_deep)
    return data


def read_json(path: str | os.PathLike, what: str, *, parse_constant: Callable[[str], Any] | None = None):
    """The JSON in the file ``path`` (``parse_json``), expected to be ``what``. OSError for a file
    that cannot be opened; InputError naming the file for one that is not UTF-8 JSON text."""
    path = os.fspath(path)
    with open(path, "rb") as fh:
        raw = fh.read()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (byte {exc.start}); expected {what}") from None
    return parse_json(text, path, what, parse_constant=parse_constant)
