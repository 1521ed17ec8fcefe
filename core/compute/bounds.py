"""Check mode's float32 bound shared by the techniques that gather (``core/compute/backend.py``'s
``checked``): a technique module passes its bound to the decorator, built from these."""

from __future__ import annotations

import numpy as np

from ..base import arrays
from . import backend


def gather_bound(args: dict, reference: np.ndarray, terms: float, radius_su: float) -> np.ndarray:
    """The bound of a result that is the albedo after the scatter times a weighted average, with
    non-negative weights, of the light before it within ``radius_su`` (SSSS, Burley): its sums of
    ``terms`` terms are made of values up to the largest light there. ``args``: the technique's
    keyword arguments (``albedo``, ``diffuse``, ``depth``, ``camera``, ``albedo_mode``)."""
    a = arrays.image(args["albedo"], "albedo")
    e = arrays.image(args["diffuse"], "diffuse")
    pre, post = arrays.split_albedo(a, args.get("albedo_mode", "post"))
    light = e if pre is None else pre * e
    with np.errstate(invalid="ignore", over="ignore"):
        scale = args["camera"].pixels_per_unit(arrays.image(args["depth"], "depth", None))
    finite = scale[np.isfinite(scale)]
    with np.errstate(over="ignore"):
        reach_px = radius_su * float(finite.max()) if finite.size else 0.0
    reach = int(min(reach_px, max(light.shape[:2]))) + 2
    big = backend.local_max(light, reach)
    return backend.tolerance(terms, np.abs(post) * big)
