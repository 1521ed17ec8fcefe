"""The one mapping of technique names to functions.

The command line, the operators and the UI drop-down all read ``TECHNIQUES``; unknown names are
rejected with the list of known ones. Each technique module is imported lazily so that a caller
that needs one technique does not pay for the others.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

#: name -> (module inside ``core``, function name, label, one-line description)
TECHNIQUES: dict[str, tuple[str, str, str, str]] = {
    "sta": ("sta", "sta", "STA", "Simple translucency: back-lighting times a baked thickness map"),
    "ssss": ("ssss", "ssss", "SSSS", "Separable SSS: two 1-D per-channel convolutions"),
    "burley": ("burley", "burley", "Burley", "Christensen-Burley normalized diffusion, golden-angle spiral"),
    "combined": (
        "combined",
        "combined",
        "Combined",
        "Burley diffusion of the visible light plus Burley transmittance of the light from behind",
    ),
}


def check_technique(name: str) -> str:
    """Return ``name`` if it is a known technique, else raise ValueError listing the known ones."""
    if name not in TECHNIQUES:
        raise ValueError(f"unknown technique {name!r}; expected one of: {', '.join(TECHNIQUES)}")
    return name


def get_technique(name: str) -> Callable:
    """The technique function registered under ``name``."""
    module, func, _, _ = TECHNIQUES[check_technique(name)]
    return getattr(importlib.import_module(f"{__package__}.{module}"), func)
