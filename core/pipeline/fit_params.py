"""The parameters ``calibrate`` fits per material and technique: names, bounds, validation.

A material's fit (``MaterialSSS.fit``) maps a technique name to a dict of these values; the
scene description carries it, ``core.pipeline.mapping.technique_params`` applies it, and the Blender
side stores it on the material as custom properties (``sss_lab_fit_<technique>_<name>``).

- ``gain`` (R, G, B): multiplies the material's light after the technique, per channel (the
  energy that plain diffuse passes miss: light entering through surfaces the camera does not
  see, Cycles' albedo inversion, docs/references.md §9). For STA it multiplies the added light.
- ``d_scale``: multiplies the profile's d of every channel (Burley, SSSS, the combined
  technique's diffusion).
- ``transmission_scale`` (R, G, B) and ``transmission_d_su`` (R, G, B, scene units): the
  combined technique's light from behind (``core/techniques/combined/technique.py``): its scale and the length per
  channel of its transmittance (the random walk's mean free path, Christensen-Burley's d); a
  single number is read as the same for the three channels.
- ``scale``: STA's s_T.
- ``off`` (any technique): 1 when calibrate measured the technique worse than no SSS on the
  material's held-out pixels, fit and all; the technique then leaves the material as it is.

Anything else in the dict (``info``: samples, errors) is provenance and never read by a technique.
"""

from __future__ import annotations

from ..scene.fit_values import INFO, OFF, PARAMETERS, check_value
from ..scene.fit_values import check_fit as check_form
from ..techniques.registry import TECHNIQUES

__all__ = ["FIT_PARAMETERS", "INFO", "OFF", "PARAMETERS", "check_fit", "check_value", "fitted"]


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


def check_fit(fit, where: str) -> dict:
    """A validated copy of a material's fit whose techniques and parameters are the registered
    techniques' ``fit`` (``core.scene.fit_values.check_fit``)."""
    return check_form(fit, where, FIT_PARAMETERS)


def fitted(fit: dict, technique: str) -> dict:
    """The fitted parameters of ``technique`` (without the provenance), {} when none. ValueError
    when the fit holds a technique that has no fit or a parameter its fit does not change (the
    scene description checks a fit's values, not which technique fits what)."""
    check_fit(fit, "material")
    return {k: v for k, v in (fit or {}).get(technique, {}).items() if k != INFO}
