"""Sweeps of a technique over variants of its parameters, measured against a reference image.

``compare`` (``blender/compare.py``) renders the Cycles reference and the passes; what it then
does with a technique is pure NumPy and lives here: run it once per variant (``sweep``), and
calibrate what its spec says can be calibrated (``calibrate``): the material mapping per
subsurface method, or a grid of its parameters. A technique is a registered name or a
``Technique`` spec, so that a test can sweep a technique of its own.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from ..pipeline import apply as core_apply
from ..pipeline import mapping
from ..scene.exr import Passes
from ..scene.scene import SceneDescription
from ..techniques.registry import get_spec
from ..techniques.spec import CALIBRATE_MAPPING, Technique
from . import metrics


def mark_best(results: list[dict[str, Any]]) -> None:
    """Mark the row with the lowest error chosen, unless all are equal to 1e-4 relative (the
    technique did not change this scene, e.g. STA without light from behind): then none is."""
    errors = [r["rel_rmse"] for r in results if r.get("rel_rmse") is not None]
    if not errors or max(errors) - min(errors) <= 1e-4 * max(min(errors), 1e-12):
        return
    min((r for r in results if r.get("rel_rmse") is not None), key=lambda r: r["rel_rmse"])["chosen"] = True


def sweep(
    passes: Passes,
    desc: SceneDescription,
    ref: np.ndarray,
    mask: np.ndarray,
    box: int,
    technique: str | Technique,
    method: str,
    variants: Iterable[tuple[str, Mapping[str, Any]]],
) -> list[dict[str, Any]]:
    """Rows for ``technique`` run with each (label, options) of ``variants``: the ones that could
    not run (with the reason), then the measured ones (relative RMSE against ``ref`` over
    ``mask``, ``box``-pixel blocks), the best marked chosen."""
    spec = get_spec(technique)
    failed: list[dict[str, Any]] = []
    results: list[dict[str, Any]] = []
    for label, options in variants:
        row = {"method": method, "technique": spec.name, "mapping": label}
        try:
            layers = core_apply.apply(passes, desc, spec, **options)
        except (ValueError, KeyError) as exc:
            failed.append({**row, "rel_rmse": None, "error": str(exc)})
            continue
        if layers:
            m = metrics.compare_images(layers[core_apply.layer_names(spec.name)[0]], ref, mask, box=box)
            results.append({**row, "rel_rmse": m["rel_rmse"]})
    mark_best(results)
    return failed + results


def grid(values: Mapping[str, tuple[Any, ...]]) -> list[tuple[str, dict[str, Any]]]:
    """(label, options) for every combination of the grid's values, the first key outermost;
    a label shows text values as they are and numbers as ``name=value``."""
    runs = [dict(zip(values, combo, strict=True)) for combo in itertools.product(*values.values())]
    return [(", ".join(v if isinstance(v, str) else f"{k}={v:g}" for k, v in run.items()), run) for run in runs]


def calibrate(
    passes: Passes,
    desc: SceneDescription,
    ref: np.ndarray,
    mask: np.ndarray,
    *,
    box: int,
    techniques: Iterable[str | Technique],
) -> dict[str, Any]:
    """For each subsurface method in the scene and each technique that calibrates the mapping,
    the error of every mapping the core offers; for each technique with a parameter grid, the
    error of every point of it. The lowest of each sweep is marked chosen (none when all are equal)."""
    rows: list[dict[str, Any]] = []
    specs = [get_spec(t) for t in techniques]
    for method in sorted({m.method for m in desc.materials if m.scatters}):
        for spec in specs:
            if spec.calibration == CALIBRATE_MAPPING:
                variants = [(name, {"mapping": name}) for name in mapping.MAPPINGS.get(method, ())]
                rows += sweep(passes, desc, ref, mask, box, spec, method, variants)
    for spec in specs:
        if isinstance(spec.calibration, Mapping):
            # A technique without a physical scale (STA, core/pipeline/mapping.py): the grid of its
            # parameters (STA: its scale s_T with each thickness falloff) is what there is to calibrate.
            rows += sweep(passes, desc, ref, mask, box, spec, "any", grid(spec.calibration))
    return {
        "definition": "Each mapping from the Principled BSDF inputs to the technique's parameters"
        " (core/pipeline/mapping.py),"
        " applied to this scene's passes, and STA's scale s_T; relative RMSE against the reference as above.",
        "rows": rows,
    }
