"""The registry: every technique SSS Lab runs, in the order the command line and the panel list them.

Each entry is the ``Technique`` spec its module declares beside its function (``core/techniques/spec.py``
explains the fields). The list is explicit, no discovery: adding a technique is one line here
plus its module (``docs/adding-a-technique.md``). ``Registry`` is also what a test builds to
run a technique of its own through plan, apply and compare without touching this list.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any

import numpy as np

from ..base.errors import InputError
from . import burley, combined, ssss, sta
from .spec import Technique


class Registry(Mapping[str, Technique]):
    """Techniques by name, in registration order."""

    def __init__(self, techniques: Iterable[Technique] = ()) -> None:
        self._specs: dict[str, Technique] = {}
        for t in techniques:
            self.register(t)

    def register(self, technique: Technique) -> Technique:
        """Add ``technique``; TypeError when the name is taken or it is not a ``Technique``."""
        if not isinstance(technique, Technique):
            raise TypeError(f"expected a Technique spec, got {type(technique).__name__}")
        if technique.name in self._specs:
            raise TypeError(f"a technique named {technique.name!r} is registered already")
        self._specs[technique.name] = technique
        return technique

    def __getitem__(self, name: str) -> Technique:
        return self._specs[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._specs)

    def __len__(self) -> int:
        return len(self._specs)

    def get_spec(self, technique: str | Technique) -> Technique:
        """The spec of ``technique`` (a name, or a spec, returned as it is); InputError listing
        the known names for an unknown one."""
        if isinstance(technique, Technique):
            return technique
        spec = self._specs.get(technique) if isinstance(technique, str) else None
        if spec is None:
            raise InputError(f"unknown technique {technique!r}; expected one of: {', '.join(self._specs)}")
        return spec


#: The techniques, in the order they are listed everywhere.
TECHNIQUES = Registry((sta.TECHNIQUE, ssss.TECHNIQUE, burley.TECHNIQUE, combined.TECHNIQUE))

#: The technique the panel starts with.
DEFAULT_TECHNIQUE = burley.TECHNIQUE.name


def get_spec(technique: str | Technique) -> Technique:
    """The registered spec of ``technique`` (or the spec itself); InputError for an unknown name."""
    return TECHNIQUES.get_spec(technique)


def parse_params(texts: Iterable[str], techniques: Iterable[str | Technique]) -> dict[str, dict[str, Any]]:
    """``["n_samples=16"]`` or ``["burley.n_samples=16", "sta.power=3"]`` (the command line's
    ``--param``) -> {technique: {parameter: value}}, each value checked against the spec.

    A key names a parameter of the one technique that runs, or ``TECHNIQUE.KEY`` when several
    run. InputError, one line, for anything else: the text, and the allowed keys or range."""
    specs = [get_spec(t) for t in techniques]
    out: dict[str, dict[str, Any]] = {s.name: {} for s in specs}
    for text in texts:
        key, eq, value = str(text).partition("=")
        key = key.strip()
        where = f"--param {text}: "
        if not eq or not key:
            raise InputError(f"{where}expected KEY=VALUE, e.g. {_example(specs)}")
        name, dot, param = key.rpartition(".")
        if dot:
            spec = next((s for s in specs if s.name == name), None)
            if spec is None:
                raise InputError(f"{where}{name!r} is not among the techniques that run ({', '.join(out)})")
        elif len(specs) == 1:
            spec = specs[0]
        else:
            raise InputError(f"{where}several techniques run ({', '.join(out)}): name one, e.g. {_example(specs)}")
        try:
            parsed = spec.param(param).parse(value, f"{spec.name}.")
        except InputError as exc:
            raise InputError(where + str(exc)) from None
        if param in out[spec.name] and out[spec.name][param] != parsed:
            raise InputError(
                f"{where}{spec.name}.{param} is given twice ({out[spec.name][param]!r} and {parsed!r}); give it once"
            )
        out[spec.name][param] = parsed
    return out


def _example(specs: list[Technique]) -> str:
    """An example ``--param`` for the techniques that run."""
    qualified = len(specs) > 1
    for s in specs:
        for p in s.params:
            return f"{s.name + '.' if qualified else ''}{p.name}={p.default}"
    return "KEY=VALUE"


def check_technique(name: str) -> str:
    """Return ``name`` if it is a registered technique, else raise InputError listing the known ones."""
    return TECHNIQUES.get_spec(name).name


def get_technique(name: str | Technique) -> Callable[..., np.ndarray]:
    """The function of the technique ``name``."""
    return get_spec(name).function
