"""Call a technique's function with the keywords it takes, and no others.

Every caller (``core.pipeline.apply``, ``core.study.fit``, ``core.study.fidelity``, and through
apply ``core.study.sweep`` and ``core.pipeline.auto``) offers a technique the same set of inputs
(``docs/adding-a-technique.md``); a technique declares in its signature which of them it reads,
and ``call_technique`` passes those alone, so that a technique need not take ``depth`` or
``camera`` it does not use.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from typing import Any

from ..techniques.spec import Technique

__all__ = ["accepted_keywords", "call_technique"]


@functools.lru_cache(maxsize=64)
def accepted_keywords(func: Callable[..., Any]) -> tuple[frozenset[str], bool]:
    """(the keyword arguments ``func`` takes, whether it takes any): read once per function."""
    sig = inspect.signature(func)
    names = frozenset(p.name for p in sig.parameters.values() if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD))
    var_kw = any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values())
    return names, var_kw


def call_technique(technique: Technique | Callable[..., Any], /, **inputs: Any) -> Any:
    """Run ``technique`` (a spec or its function) on the ``inputs`` its function takes; the
    others are left out (all are passed to a function with ``**kwargs``)."""
    func = technique.function if isinstance(technique, Technique) else technique
    accepted, var_kw = accepted_keywords(func)
    if not var_kw:
        inputs = {k: v for k, v in inputs.items() if k in accepted}
    return func(**inputs)
