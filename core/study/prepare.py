"""Compile the kernels before they are needed (``python -m sss_lab prepare``; the extension starts
it in the background once per installed version).

Numba compiles each compiled kernel (each owner's ``_kernels.py``) on its first call, for the types of the
arrays it is given, and keeps the machine code in the on-disk cache (``core/compute/backend.py``). With
an empty cache, the first ``apply`` of a technique waits for that: 10 to 20 s for STA, SSSS or
Burley and about as much again for the combined technique's light from behind on this project's
2-core machine (``first_call_s`` in ``benchmarks/results/speed.json``). ``prepare_kernels`` makes
those first calls on a small synthetic frame (``core.study.synthetic.sphere_scene``: a Christensen-Burley
skin sphere and a Random Walk wax one, every pass a real render gives) through ``core.pipeline.apply``,
the path each frame takes (and, for a technique with a composite route, its generic route too:
the materials the route does not take and the fit run that), and measures ``apply --methods
auto``'s features of each material on it, so that the cache holds what a frame needs; a later
process loads each kernel from it in a fraction of a second. The frame is applied twice per technique: as built
(no thickness bake distance: the energy stage's "object" path) and with a bake distance and long
lengths (``FAR``), whose light from behind is spread far enough to use the spread's reduced
levels; the latter once more with the light from behind streamed as frames of 2^20 pixels and
more have it (``core.techniques.combined.back_light.STREAM_FROM_PIXELS``). A frame whose inputs have other types
(another integer type of Object Index, say) still compiles what it needs on first use.

The cache is keyed by the kernels' sources (their digest names the cache folder, and Numba checks
each file's time stamp and size), so a
new version of the extension, or the same one installed again, prepares again: ``marker_path``
names the file that records that these kernels were prepared.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import sys
import time

from ..base import files
from ..base.errors import SSSLabError
from ..compute import backend

#: The synthetic frame's size: enough pixels for every kernel's paths (the spheres' edges, the
#: plane behind them), small enough to cost nothing but the compiling.
SIZE = (64, 48)
#: The second variant's materials: a thickness bake distance (scene units) and a Subsurface Scale
#: whose light from behind spreads over 16 pixels and more at ``SIZE`` (the spread's reduced
#: levels, ``core.techniques.combined.technique.SPREAD_COARSE_FROM_PX``; scale 1 stays below them, 3 reaches the first).
FAR = {"thickness_distance": 0.5, "subsurface_scale": 10.0}
#: ``prepare_kernels``'s unit for ``apply --methods auto``'s features (beside the techniques' names).
AUTO = "auto"
#: The most worker processes ``prepare_kernels(jobs=...)`` starts: one per unit is all it can use.
MAX_JOBS = 64


class PrepareError(SSSLabError):
    """The compiled kernels cannot be prepared (Numba cannot load): the techniques run on NumPy."""


def _digest() -> str:
    """What the cache's contents depend on: the kernels' sources and their files' time stamps, Python's
    and Numba's versions (Numba's from its package metadata: this does not import it, which takes
    a good part of a second)."""
    from importlib import metadata

    try:
        numba_version = metadata.version("numba")
    except metadata.PackageNotFoundError:
        numba_version = "none"
    h = hashlib.sha256(backend.kernel_digest().encode())
    # Numba's cache index holds each file's time stamp and size: a reinstall of the same version
    # (files unpacked anew) misses its cache, and so must the marker.
    for source in backend.kernel_sources():
        st = os.stat(source)
        h.update(f"{os.path.basename(source)}:{st.st_mtime}:{st.st_size}".encode())
    h.update(f"{sys.version_info[:2]}:{numba_version}".encode())
    return h.hexdigest()[:16]


def marker_path() -> str:
    """The file in the cache folder that says this version's kernels were prepared there."""
    return os.path.join(backend.kernel_cache_dir(), f"prepared-{_digest()}.json")


def is_prepared() -> bool:
    """Whether ``prepare_kernels`` ran to the end for this version and cache folder (False where
    Numba cannot load)."""
    if backend.compiled() is None:
        return False
    return os.path.isfile(marker_path())


def synthetic_frame():
    """The small frame kernels are prepared on: (its passes, its scene description, the same scene
    with ``FAR``'s materials), ``core.study.synthetic.sphere_scene`` at ``SIZE``."""
    from ..scene.exr import Passes
    from .synthetic import sphere_scene

    arrays, scene = sphere_scene(*SIZE)
    far = dataclasses.replace(
        scene, materials=tuple(dataclasses.replace(m, **FAR) if m.scatters else m for m in scene.materials)
    )
    return Passes(arrays), scene, far


def _warm(units, log=None) -> None:
    """Make ``apply``'s first calls for each unit of ``units`` (a technique's name, or ``AUTO`` for
    ``apply --methods auto``'s features) on the synthetic frame, on the compiled backend."""
    from ..pipeline.apply import apply
    from ..techniques.combined.back_light import streaming_every_region
    from ..techniques.registry import get_spec

    passes, scene, far = synthetic_frame()
    with backend.use("numba"):
        for name in units:
            if name == AUTO:
                # ``apply --methods auto`` measures each material before any technique runs.
                from ..pipeline.auto import features

                if log is not None:
                    log("auto: compiling or loading its features' kernels")
                for material in far.materials:
                    if material.scatters:
                        features(passes, far, material)
                continue
            if log is not None:
                log(f"{name}: compiling or loading its kernels")
            spec = get_spec(name)
            for variant in (scene, far):
                apply(passes, variant, name)
                if spec.composite is not None:
                    # Its generic route too: materials the route does not take, and the fit's calls.
                    apply(passes, variant, dataclasses.replace(spec, composite=None))
            # Frames from ``core.techniques.combined.back_light.STREAM_FROM_PIXELS`` on stream the light from behind.
            with streaming_every_region():
                apply(passes, far, name)


def _warm_in_worker(unit: str, cache_dir: str) -> str:
    """One unit of ``_warm`` in a worker process of ``prepare_kernels(jobs=...)``, into ``cache_dir``."""
    backend.set_cache_dir(cache_dir)
    _warm((unit,))
    return unit


def _warm_in_parallel(units: list[str], jobs: int, log=None) -> None:
    """``_warm`` each unit in a pool of ``jobs`` fresh processes (Numba compiles on one core: the
    units compile side by side). The processes are started afresh (spawn), so that none inherits
    a half-loaded Numba; a kernel two units share is compiled by both, and the cache keeps one."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    cache = backend.cache_dir()
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
        pending = [pool.submit(_warm_in_worker, unit, cache) for unit in units]
        for done in as_completed(pending):
            unit = done.result()
            if log is not None:
                log(f"{unit}: compiled in a worker process")


def prepare_kernels(techniques=None, *, log=None, jobs: int = 1) -> dict:
    """Compile (or load from the cache) every kernel ``core.pipeline.apply.apply`` runs for each technique of
    ``techniques`` (default: all registered, and ``apply --methods auto``'s features) on ``SIZE``'s
    synthetic frame, on the compiled backend whatever ``SSS_LAB_BACKEND`` says; then write
    ``marker_path()`` (all techniques only).

    ``jobs`` > 1 compiles the techniques in that many worker processes first (``_warm_in_parallel``),
    then loads them all here from the cache, as with one job, so that what this process returns and
    marks is what it loaded itself.

    Returns {"cache_dir", "seconds" (the whole), "kernels": {name: seconds of its first call in
    this process: compiling, or loading from the cache}}. ``log(line)`` is told each technique
    before it runs. Raises ``PrepareError`` where Numba cannot load, ``ValueError`` for a ``jobs``
    that is not a whole number from 1 to ``MAX_JOBS``."""
    from ..techniques.registry import TECHNIQUES, check_technique

    if isinstance(jobs, bool) or not isinstance(jobs, int) or not 1 <= jobs <= MAX_JOBS:
        raise ValueError(f"jobs: expected a whole number from 1 to {MAX_JOBS}, got {jobs!r}")
    if backend.compiled() is None:
        raise PrepareError(
            f"Numba cannot load ({backend.unavailable_reason()}): the techniques run on their NumPy "
            "implementations, and there is nothing to compile"
        )
    names = list(TECHNIQUES) if techniques is None else [check_technique(t) for t in techniques]
    units = names + ([AUTO] if techniques is None else [])
    start = time.perf_counter()
    if jobs > 1 and len(units) > 1:
        _warm_in_parallel(units, min(jobs, len(units)), log)
    before = set(backend.first_call_seconds())
    _warm(units, log)
    seconds = time.perf_counter() - start
    kernels = {k: v for k, v in backend.first_call_seconds().items() if k not in before and k != "import"}
    result = {"cache_dir": backend.cache_dir(), "seconds": seconds, "kernels": kernels}
    if techniques is None:
        marker = marker_path()  # hashes the kernels' sources: once
        os.makedirs(os.path.dirname(marker), exist_ok=True)
        files.write_text(marker, json.dumps({"seconds": round(seconds, 3), "kernels": sorted(kernels)}))
    return result
