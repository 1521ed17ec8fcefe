"""Fit to Cycles: fit each subsurface material's technique parameters to a short random-walk render.

``calibrate(scene)`` renders the scene's own view twice — Cycles random walk at a few dozen
samples (fixed seed, adaptive sampling off, docs/references.md §8) and the passes the techniques
need — fits per material and technique with ``core.study.fit.fit_scene``, and stores the fitted values
on each material as custom properties ``sss_lab_fit_<technique>_<parameter>`` (plus
``sss_lab_fit_<technique>_info``, a JSON string with the samples and the held-out errors;
``blender/stored.py`` reads and writes them). The scene description reads them back
(``describe.material_sss``), so Render Passes, Apply, Compare and the command line use them with
no extra option. The properties are shown and editable in the panel and cleared by Clear Fit
(``bpy.ops.sss_lab.fit_to_cycles`` and ``stored.clear_fit``: ``operators/fit.py``).

The scene is left as it was apart from the new properties (``SceneState``); a material that
cannot be fitted (too few pixels, no bake distance, a fit that does not hold) keeps its old
values, and the reason is one line in the result.
"""

from __future__ import annotations

import functools
import os
import time

import bpy

from ..core.base import files
from ..core.base.errors import InputError
from ..core.compute import backend
from ..core.pipeline.fit_params import FIT_PARAMETERS
from ..core.pipeline.sequence import load_scene
from ..core.scene import exr
from ..core.scene.scene import parse_resolution
from ..core.study.fit import (
    BOX,
    BUDGET,
    MAX_SAMPLES,
    after_second_fit,
    fit_scene,
    mean_render,
    more_samples,
    refused_pairs,
)
from ..core.techniques.registry import TECHNIQUES
from .describe import sss_materials
from .jobs import Job, Steps, run
from .reference_cache import render_combined
from .render_passes import render_passes
from .state import SceneState
from .stored import write_fit
from .thickness import thickness_aov_name, thickness_setup

#: The techniques ``calibrate`` fits by default: the two that the fit improves most.
DEFAULT_TECHNIQUES = ("burley", "combined")


#: The techniques whose fit this process has run once (``_start_up``).
_STARTED: set = set()


def _start_up(techniques) -> dict:
    """What a process does once before its first fit of ``techniques``, done on the small synthetic
    frame ``core.study.prepare`` compiles the kernels on (``synthetic_frame``): importing the fit's modules,
    loading (or compiling) the compiled kernels, building the energy stage's and the light from
    behind's tables. Returns {"start_up": its seconds} ({} when nothing was left to do); the fit
    that follows then takes what it takes on every later call, which is what ``calibrate``'s
    budget counts (``benchmarks/fit.py`` measures the fit the same way)."""
    todo = tuple(t for t in techniques if t not in _STARTED)
    if not todo:
        return {}
    from ..core.study import fit as core_fit
    from ..core.study.prepare import synthetic_frame

    start = time.perf_counter()
    # The frame with a bake distance, so that the combined technique's light from behind runs too.
    passes, _scene, far = synthetic_frame()
    core_fit.fit_scene(passes, far, passes["Combined"], techniques=todo)
    _STARTED.update(todo)
    return {"start_up": time.perf_counter() - start}


def calibrate(scene, **options) -> dict:
    """Fit the scene's subsurface materials to Cycles random walk and store the fits on them
    (``calibrate_job`` run to its end; ``options`` are its keywords).

    Returns {"results": [FitResult.to_dict()], "problems": [one line each], "seconds": {"reference",
    "passes", "fit"}}. Raises InputError (nothing changed) for bad arguments, a scene without a
    camera or without subsurface materials.
    """
    return run(calibrate_job(scene, **options))


def _check(scene, *, techniques, samples, max_samples, pass_samples, box, budget) -> tuple[tuple, int, list]:
    """(techniques, max_samples, the scene's subsurface materials) for ``calibrate_job``;
    InputError for a bad argument, a scene without a camera or without subsurface materials."""
    techniques = tuple(techniques)
    if max_samples is None:
        max_samples = max(samples, MAX_SAMPLES) if isinstance(samples, int) and not isinstance(samples, bool) else 1
    for t in techniques:
        if t not in FIT_PARAMETERS:
            raise InputError(f"methods: no fit exists for {t!r}; expected some of: {', '.join(FIT_PARAMETERS)}")
    for name, value in (
        ("samples", samples),
        ("max_samples", max_samples),
        ("pass_samples", pass_samples),
        ("box", box),
    ):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError(f"{name}: expected an integer >= 1, got {value!r}")
    if max_samples < samples:
        raise InputError(f"max_samples: expected at least samples ({samples}), got {max_samples}")
    if isinstance(budget, bool) or not isinstance(budget, (int, float)) or not 0.0 <= budget <= 1.0:
        raise InputError(f"budget: expected a share of the reference render from 0 to 1, got {budget!r}")
    if scene.camera is None:
        raise InputError(f"scene {scene.name!r} has no active camera; set one in Scene Properties > Camera")
    materials = sss_materials(scene)
    if not materials:
        raise InputError(
            f"scene {scene.name!r} has no material with subsurface scattering (Subsurface Weight > 0): nothing to fit"
        )
    return techniques, max_samples, materials


def _with_maps(scene, techniques: tuple, materials: list, log) -> tuple[tuple, list[str]]:
    """(the techniques that can be fitted, problems): a technique that reads the thickness map is
    left out, with one line saying why, when the scene's maps do not serve it; InputError when
    none is left."""
    problems: list[str] = []
    needs_map = [t for t in techniques if TECHNIQUES[t].reads_thickness]
    if needs_map:
        try:
            thickness_setup(scene, materials, thickness_aov_name(scene))
        except ValueError as exc:
            techniques = tuple(t for t in techniques if t not in needs_map)
            problems.append(f"{', '.join(needs_map)} not fitted: {exc}")
            log(problems[-1])
            if not techniques:
                raise InputError(problems[-1]) from None
    return techniques, problems


def _passes(scene, folder: str, *, techniques, pass_samples, resolution, seed, seconds, log) -> tuple:
    """(passes, scene description) rendered into ``folder``; their seconds go to ``seconds``."""
    log(f"Passes, {pass_samples} samples")
    start = time.perf_counter()
    written = render_passes(
        scene,
        os.path.join(folder, "passes"),
        techniques=techniques,
        samples=pass_samples,
        resolution=resolution,
        seed=seed,
        overwrite=True,
        log=log,
    )
    seconds["passes"] = time.perf_counter() - start
    exr_path = next(p for p in written if p.endswith(".exr"))
    return exr.read_passes(exr_path), load_scene(exr_path)


def _more_samples(
    steps: Steps,
    render,
    folder: str,
    fit,
    *,
    reference,
    results,
    fit_problems,
    refused,
    samples,
    max_samples,
    budget,
    seed,
    seconds,
    once,
    log,
):
    """The steps after a first fit some of whose fits the held-out check refused (the render may
    be too noisy for them): a one-sample pilot render, then, if the cost stays within the budget
    (``core.study.fit.more_samples``), more samples and a second fit of the refused materials on the two
    renders' mean. ``render(samples, seed, path)``: a timed random-walk render; ``fit(reference,
    samples=, only=)``: the first fit's ``fit_scene`` on other samples. Adds the second fit's
    results to ``results``; a job's steps, returning the problems that stand after it."""
    steps.total = 5
    yield steps.next("a one-sample pilot render, to estimate the cost of more samples")
    seconds["pilot"] = render(1, seed + 2, os.path.join(folder, "pilot.exr"))
    fit_s = seconds["fit"] - once
    extra, why = more_samples(
        samples=samples,
        max_samples=max_samples,
        spent_s=seconds["reference"] + seconds["passes"] + fit_s + seconds["pilot"],
        render_s=seconds["reference"],
        pilot_s=seconds["pilot"],
        fit_s=fit_s,
        budget=budget,
    )
    log(f"{len(refused)} fit(s) refused by the held-out check; {why}")
    if not extra:
        return fit_problems + [f"not rendered again for the refused fits: {why}"]
    yield steps.next(f"Cycles random walk, {extra} more samples, and a second fit of {len(refused)}")
    more_path = os.path.join(folder, "more.exr")
    seconds["more"] = render(extra, seed + 1, more_path)
    reference = mean_render(reference, samples, exr.read_passes(more_path)["Combined"], extra)
    start = time.perf_counter()
    redo, redo_problems = fit(reference, samples=samples + extra, only=refused_pairs(refused))
    seconds["fit_more"] = time.perf_counter() - start
    results += redo
    # The second fit's outcome replaces the first's refusals.
    return after_second_fit(fit_problems, refused, redo_problems)


def _store(results, problems: list[str]) -> None:
    """Write each fit on its material; a material renamed while fitting is one more problem."""
    for r in results:
        material = bpy.data.materials.get(r.material)
        if material is None:  # renamed while fitting: nothing to store it on
            problems.append(f"material {r.material!r} no longer exists: its fit is not stored")
            continue
        write_fit(material, r.technique, r.params)


def calibrate_job(
    scene,
    *,
    techniques=DEFAULT_TECHNIQUES,
    samples: int = 32,
    max_samples: int | None = None,
    budget: float = BUDGET,
    pass_samples: int = 16,
    resolution=None,
    seed: int = 0,
    box: int = BOX,
    log=print,
) -> Job:
    """``calibrate`` as a job (``blender/jobs.py``): the random-walk render, the passes (16 samples
    by default: the fit averages blocks (``core.study.fit.BOX``), and on the fidelity suite 16 and 64
    samples give the same share of the error removed on frame A within 1 point,
    ``benchmarks/fit.py``), the fit; then, for the fits the held-out check refused (the render may
    be too noisy for them), a one-sample pilot render and, when ``core.study.fit.more_samples`` finds
    the cost within ``budget`` of the render the fit stands in for, a render of ``max_samples`` -
    ``samples`` more samples (seed + 1) and a second fit of those materials on the two renders'
    mean. The budget counts the renders, the passes and the fits, not what a process does once
    before its first fit (``_start_up``: importing, loading the compiled kernels, building tables;
    about a second, reported as ``seconds["start_up"]``). ``max_samples`` None: ``MAX_SAMPLES`` (64,
    the top of the range the fit is measured on), or ``samples`` when that is more. Its checks
    raise before the first ``yield``; the materials are written only after the last step, so that
    a job closed between steps (Esc in the panel) leaves every material as it was (the scene
    itself is restored by the renders' own ``SceneState``)."""
    techniques, max_samples, materials = _check(
        scene,
        techniques=techniques,
        samples=samples,
        max_samples=max_samples,
        pass_samples=pass_samples,
        box=box,
        budget=budget,
    )
    resolution = parse_resolution(resolution) if resolution is not None else None
    techniques, problems = _with_maps(scene, techniques, materials, log)
    seconds: dict[str, float] = {}
    steps = Steps(3)

    def render(n: int, s: int, path: str) -> float:
        with SceneState() as state:
            return render_combined(scene, samples=n, seed=s, resolution=resolution, path=path, state=state)

    yield steps.next(f"Cycles random walk, {samples} samples")
    with files.temporary_folder("sss_lab_fit_") as tmp:
        log(f"Cycles random walk, {samples} samples (seed {seed})")
        ref_path = os.path.join(tmp, "reference.exr")
        seconds["reference"] = render(samples, seed, ref_path)
        reference = exr.read_passes(ref_path)["Combined"]
        yield steps.next(f"passes, {pass_samples} samples")
        passes, desc = _passes(
            scene,
            tmp,
            techniques=techniques,
            pass_samples=pass_samples,
            resolution=resolution,
            seed=seed,
            seconds=seconds,
            log=log,
        )
        yield steps.next(f"fit of {len(materials)} material(s)")
        seconds.update(_start_up(techniques))
        once = sum(backend.first_call_seconds().values())
        start = time.perf_counter()
        refused: list = []
        results, fit_problems = fit_scene(
            passes, desc, reference, techniques=techniques, box=box, samples=samples, log=log, refused=refused
        )
        seconds["fit"] = time.perf_counter() - start
        # A kernel the start-up did not load (another array type) loads on its first call here.
        once = min(max(sum(backend.first_call_seconds().values()) - once, 0.0), seconds["fit"])
        if refused and max_samples > samples:
            fit = functools.partial(fit_scene, passes, desc, techniques=techniques, box=box, log=log)
            fit_problems = yield from _more_samples(
                steps,
                render,
                tmp,
                fit,
                reference=reference,
                results=results,
                fit_problems=fit_problems,
                refused=refused,
                samples=samples,
                max_samples=max_samples,
                budget=budget,
                seed=seed,
                seconds=seconds,
                once=once,
                log=log,
            )
    problems += fit_problems
    _store(results, problems)
    return {"results": [r.to_dict() for r in results], "problems": problems, "seconds": seconds}
