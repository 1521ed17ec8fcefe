"""The parameters ``calibrate`` fits per material and technique: names, bounds, validation.

A material's fit (``MaterialSSS.fit``) maps a technique name to a dict of these values; the
scene description carries it, ``core.mapping.technique_params`` applies it, and the Blender
side stores it on the material as custom properties (``sss_lab_fit_<technique>_<name>``).

- ``gain`` (R, G, B): multiplies the material's light after the technique, per channel (the
  energy that plain diffuse passes miss: light entering through surfaces the camera does not
  see, Cycles' albedo inversion, docs/references.md §9). For STA it multiplies the added light.
- ``d_scale``: multiplies the profile's d of every channel (Burley, SSSS, the combined
  technique's diffusion).
- ``transmission_scale`` (R, G, B) and ``transmission_d_su`` (R, G, B, scene units): the
  combined technique's light from behind (``core/combined.py``): its scale and the length per
  channel of its transmittance (the random walk's mean free path, Christensen-Burley's d); a
  single number is read as the same for the three channels.
- ``scale``: STA's s_T.

Anything else in the dict (``info``: samples, errors) is provenance and never read by a technique.
"""

from __future__ import annotations

import math

from .techniques import TECHNIQUES

#: name -> (number of values, lower bound, upper bound). The fit never leaves these bounds, and
#: a hand-edited value outside them is rejected with the bounds in the message.
PARAMETERS: dict[str, tuple[int, float, float]] = {
    "gain": (3, 0.25, 4.0),
    "d_scale": (1, 0.25, 4.0),
    "transmission_scale": (3, 0.0, 16.0),
    "transmission_d_su": (3, 0.0, 1e6),
    "scale": (1, 0.0, 64.0),
}


def _fit_parameters() -> dict[str, tuple[str, ...]]:
    """Each registered technique's ``fit`` (its spec's), checked against ``PARAMETERS``."""
    out = {}
    for t in TECHNIQUES.values():
        unknown = [name for name in t.fit if name not in PARAMETERS]
        if unknown:
            raise TypeError(f"technique {t.name!r}: fit names {unknown}, which are not in fit_params.PARAMETERS")
        if t.fit:
            out[t.name] = t.fit
    return out


#: The techniques a fit exists for and what it may change (their specs' ``fit``), in the
#: registry's order.
FIT_PARAMETERS: dict[str, tuple[str, ...]] = _fit_parameters()

#: Key of the provenance entry (fit samples, errors before and after, pixels).
INFO = "info"


def check_value(name: str, value, where: str):
    """``value`` as a float or a 3-tuple of floats within the bounds of ``name``; ValueError naming
    ``where``, the parameter, the value and the bounds otherwise."""
    count, lo, hi = PARAMETERS[name]
    if count == 3 and isinstance(value, (int, float)) and not isinstance(value, bool):
        value = (value, value, value)
    try:
        values = [float(v) for v in value] if count == 3 else [float(value)]
    except (TypeError, ValueError):
        values = None
    if values is None or len(values) != count:
        what = "three numbers (R, G, B)" if count == 3 else "a number"
        raise ValueError(f"{where} fitted {name}: expected {what}, got {value!r}")
    for v in values:
        if not (math.isfinite(v) and lo <= v <= hi):
            raise ValueError(f"{where} fitted {name}: {value!r} is outside {lo:g}..{hi:g}")
    return tuple(values) if count == 3 else values[0]


def check_fit(fit, where: str) -> dict:
    """A validated copy of a material's fit: {technique: {parameter: value, "info": {...}}}."""
    if fit is None:
        return {}
    if not isinstance(fit, dict):
        raise ValueError(f"{where} fit: expected a mapping technique -> parameters, got {type(fit).__name__}")
    out = {}
    for technique, params in fit.items():
        if technique not in FIT_PARAMETERS:
            raise ValueError(
                f"{where} fit: unknown technique {technique!r}; expected one of: {', '.join(FIT_PARAMETERS)}"
            )
        if not isinstance(params, dict):
            raise ValueError(f"{where} fit for {technique}: expected a mapping of parameters, got {params!r}")
        clean = {}
        for name, value in params.items():
            if name == INFO:
                clean[name] = dict(value) if isinstance(value, dict) else {}
                continue
            if name not in FIT_PARAMETERS[technique]:
                raise ValueError(
                    f"{where} fit for {technique}: unknown parameter {name!r}; expected: "
                    f"{', '.join(FIT_PARAMETERS[technique])}"
                )
            clean[name] = check_value(name, value, f"{where} {technique}")
        if clean:
            out[technique] = clean
    return out


def fitted(fit: dict, technique: str) -> dict:
    """The fitted parameters of ``technique`` (without the provenance), {} when none."""
    return {k: v for k, v in (fit or {}).get(technique, {}).items() if k != INFO}
