"""The values a fit to Cycles may hold, as the scene description carries them (``MaterialSSS.fit``:
technique name -> {parameter: value, "info": provenance}): each parameter's bounds and the checks
of a fit's form. Which technique fits which parameters is its spec's ``fit``
(``core.pipeline.fit_params.FIT_PARAMETERS``), checked where a technique's fit is read (``fitted``)."""

from __future__ import annotations

import math
from collections.abc import Mapping

#: name -> (number of values, lower bound, upper bound). The fit never leaves these bounds, and
#: a hand-edited value outside them is rejected with the bounds in the message.
PARAMETERS: dict[str, tuple[int, float, float]] = {
    "gain": (3, 0.25, 4.0),
    "d_scale": (1, 0.25, 4.0),
    "transmission_scale": (3, 0.0, 16.0),
    "transmission_d_su": (3, 0.0, 1e6),
    "scale": (1, 0.0, 64.0),
    "off": (1, 0.0, 1.0),
}

#: The parameter every technique's fit may hold besides its own: 1 when ``calibrate`` measured
#: the technique worse than no SSS on the material's held-out pixels even after the fit; the
#: technique then leaves the material as it is (``core/pipeline/plan.py`` says why).
OFF = "off"


#: Key of the provenance entry (fit samples, errors before and after, pixels).
INFO = "info"


def check_value(name: str, value, where: str):
    """``value`` as a float or a 3-tuple of floats within the bounds of ``name``; ValueError naming
    ``where``, the parameter, the value and the bounds otherwise."""
    count, lo, hi = PARAMETERS[name]
    given = value  # as written, for the messages
    if count == 3 and isinstance(value, (int, float)) and not isinstance(value, bool):
        value = (value, value, value)
    try:
        values = [float(v) for v in value] if count == 3 else [float(value)]
    except (TypeError, ValueError):
        values = None
    if values is None or len(values) != count:
        what = "three numbers (R, G, B)" if count == 3 else "a number"
        raise ValueError(f"{where} fitted {name}: expected {what}, got {given!r}")
    for v in values:
        if not (math.isfinite(v) and lo <= v <= hi):
            raise ValueError(f"{where} fitted {name}: {given!r} is outside {lo:g}..{hi:g}")
    return tuple(values) if count == 3 else values[0]


def check_fit(fit, where: str, fit_parameters: Mapping[str, tuple[str, ...]] | None = None) -> dict:
    """A validated copy of a material's fit: {technique: {parameter: value, "info": {...}}}. With
    ``fit_parameters`` (technique -> the parameters its fit may change) every technique and parameter
    must be among them; without, every parameter must be one of ``PARAMETERS``."""
    if fit is None:
        return {}
    if not isinstance(fit, dict):
        raise ValueError(f"{where} fit: expected a mapping technique -> parameters, got {type(fit).__name__}")
    out = {}
    for technique, params in fit.items():
        if fit_parameters is not None and technique not in fit_parameters:
            raise ValueError(
                f"{where} fit: unknown technique {technique!r}; expected one of: {', '.join(fit_parameters)}"
            )
        if not isinstance(params, dict):
            raise ValueError(f"{where} fit for {technique}: expected a mapping of parameters, got {params!r}")
        clean = {}
        for name, value in params.items():
            if name == INFO:
                clean[name] = dict(value) if isinstance(value, dict) else {}
                continue
            allowed = PARAMETERS if fit_parameters is None else (*fit_parameters[technique], OFF)
            if name not in allowed:
                raise ValueError(
                    f"{where} fit for {technique}: unknown parameter {name!r}; expected: {', '.join(allowed)}"
                )
            clean[name] = check_value(name, value, f"{where} {technique}")
        if clean:
            out[technique] = clean
    return out
