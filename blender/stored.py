"""What SSS Lab stores on Blender data, read and written in one place.

- The fit to Cycles (``blender.calibrate``), on each material: custom properties
  ``sss_lab_fit_<technique>_<parameter>`` (``fit_key``) and ``sss_lab_fit_<technique>_info``
  (a JSON string with the samples and the held-out errors). ``read_fit`` gives them back,
  validated, to the scene description (``describe.material_sss``); the panel shows them.
- The thickness bake's settings (``blender.bake``), with each map it leaves: on the mesh, one
  entry per attribute, or on the image, under ``META_KEY`` (``thickness_metadata``).
- The Subsurface Weight the last compositor set-up saw, on each subsurface material
  (``KEPT_WEIGHT``, ``blender/compositor.py``).

It sits below the modules that read a scene (``describe``) and those that write it (the fit,
the bake, the compositor set-up), so that reading a scene never reaches up into a job.
"""

from __future__ import annotations

import json
from typing import Any

from ..core.base.jsonfile import parse_json
from ..core.pipeline.fit_params import FIT_PARAMETERS, INFO, OFF, PARAMETERS, check_fit

#: Custom-property prefix of the fitted values on a material.
PREFIX = "sss_lab_fit_"

#: Custom property holding the bake settings, on the mesh (per attribute) or on the image.
META_KEY = "sss_lab_thickness"

#: Custom property on a material: the Subsurface Weight the last compositor set-up saw.
KEPT_WEIGHT = "sss_lab_subsurface_weight"


def fit_key(technique: str, name: str) -> str:
    return f"{PREFIX}{technique}_{name}"


def read_fit(material) -> dict:
    """The fit stored on ``material``'s custom properties, validated ({} when none).

    A hand-edited value outside its bounds raises ValueError naming the material and the bounds."""
    fit: dict = {}
    keys = set(material.keys())
    for technique, names in FIT_PARAMETERS.items():
        params: dict[str, Any] = {}
        for name in (*names, OFF):
            key = fit_key(technique, name)
            if key in keys:
                value = material[key]
                params[name] = tuple(value) if hasattr(value, "__len__") else float(value)
        if params:
            info = material.get(fit_key(technique, INFO))
            try:
                params[INFO] = (
                    parse_json(info, f"material {material.name!r}", "a fit's provenance")
                    if isinstance(info, str)
                    else {}
                )
            except ValueError:
                params[INFO] = {}
            fit[technique] = params
    return check_fit(fit, f"material {material.name!r}")


def write_fit(material, technique: str, params: dict) -> None:
    """Store ``params`` (``core/pipeline/fit_params.py`` names, plus ``info``) on ``material`` for ``technique``,
    replacing that technique's earlier fit."""
    clear_fit(material, technique)
    for name, value in params.items():
        if name == INFO:
            material[fit_key(technique, INFO)] = json.dumps(value, sort_keys=True)
            continue
        key = fit_key(technique, name)
        material[key] = list(value) if isinstance(value, (tuple, list)) else float(value)
        ui = material.id_properties_ui(key)
        _, lo, hi = PARAMETERS[name]
        ui.update(min=lo, max=hi, description=f"Fitted to Cycles by SSS Lab ({technique}); Clear Fit removes it")


def clear_fit(material, technique: str | None = None) -> list[str]:
    """Remove the fitted properties of ``technique`` (all techniques when None); returns the keys removed."""
    prefix = PREFIX if technique is None else fit_key(technique, "")
    removed = [k for k in material.keys() if k.startswith(prefix)]
    for k in removed:
        del material[k]
    return removed


def thickness_metadata(idblock, attribute: str | None = None) -> dict | None:
    """The settings stored with a baked map: ``image`` or (``mesh``, attribute name); None if
    SSS Lab did not bake it."""
    meta = idblock.get(META_KEY)
    if meta is None:
        return None
    meta = meta.to_dict() if hasattr(meta, "to_dict") else dict(meta)
    if attribute is not None:
        meta = meta.get(attribute)
    return dict(meta) if meta is not None else None
