"""``apply --methods auto`` validated leave-one-scene-out: ``.venv/bin/python -m benchmarks.auto``.

For every scene (the fidelity suite, ``benchmarks/fidelity``, when it is present; else the four
sample scenes with references rendered here, ``--source samples``):

1. each technique at every rung ``core.pipeline.auto.variants`` lists (its quality ladder, the runs ``compare``
   sweeps, and each diffusion without its energy stage; at its default quality only with
   ``--no-rungs``) on the scene's passes, and no SSS: relative RMSE against
   the scene's Cycles reference over the subsurface pixels after 2 x 2 box downsampling (the
   measure ``compare`` and the fidelity suite use, docs/references.md §8), over the whole scene
   and per material; apply time (process CPU time on one thread, fastest of ``--repeat`` runs) on the same
   passes repeated ``--time-scale`` x ``--time-scale`` per pixel with the camera as many times
   finer (at the suite's 128 px a technique takes a few ms and fixed costs would dominate);
2. the features of every material (``core.pipeline.auto.features``).

Then, for each scene in turn, the auto model is learnt on the *other* scenes only
(``core.pipeline.auto.train``: coefficients and a cost rate for every rung measured there) and ``auto`` runs
on the held-out scene with it, scored the same way, and timed the same way (its features and
choice included), with every rung a candidate (``apply --methods auto --auto-rungs``). In the same
run, a second model learnt on no SSS and the techniques' default qualities only
(``techniques_only``: ``auto`` as a chooser of techniques, ``apply --methods auto``'s default) is
validated the same way, so that the two choosers are compared on the same measurements and machine
load. Per scene:

- **regret** = auto's error / the error of the truly best single choice (the best of no SSS and
  every technique at default quality, known only from the reference) - 1 (``regret_any_rung``:
  against the best of no SSS and every technique at every rung);
- **time saved** = 1 - auto's time (its features and choice included) / the time of the most
  expensive technique (the one with the largest total time over the scenes, run on every scene),
  per scene and over the suite (1 - sum of auto's times / sum of that technique's); the two timed
  in turn, call by call (``time_saved_total_separate``: against that technique's time from step 1,
  measured apart, as before);
- **the most a chooser could save** (``oracle_time_saved_total``): per scene the cheapest choice
  whose true error is within ``--max-error`` of the best (known only from the reference), over
  the suite against the same most expensive technique: how much the techniques' measured costs
  leave to save at all; with ``--quality-oracle`` the same over every rung of each technique's
  quality ladder and each diffusion without its energy stage (``quality_oracle``).

With ``--fit``, the same again with each scene fitted as ``calibrate`` fits it (``benchmarks/fit.py``'s
render and passes: Cycles random walk of the same view at 32 samples and passes at 16, its own
seed, cached in ``out/fidelity_cache/fit``; ``core.study.fit.fit_scene`` for every technique that has
a fit, or ``--fit-methods``, with ``calibrate``'s second render for the fits its held-out check
refuses, ``benchmarks.fit.fit_like_calibrate``): auto then chooses by the errors the fit measured
(``core.pipeline.auto.measured_errors``), and **regret with the fit** = auto's error / the lowest error of
no SSS and every technique at default quality, unfitted *or* fitted - 1 (the fitted techniques
count among the choices). Its time saved is against the same unfitted most expensive technique
(a fit changes a technique's parameters, not its work); the fit's own cost (a one-off per asset,
``benchmarks/fit.py``) is not in it.

Nothing here knows a scene by name: every scene is scored the same way. ``--write-model`` stores
the model learnt on all scenes but the held-out third (``benchmarks/fidelity/scenes.py``
``held_out``) as ``core/pipeline/auto_model.json`` (what ``apply --methods auto`` ships).
Writes ``benchmarks/results/auto.json`` and prints a table. Timing on a loaded shared 2-core
machine: indicative, fastest of the repeats.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results", "auto.json")
SAMPLE_SCENES = ("head_frontlit", "backlit_thin", "wax_marble", "depth_leak")
BOX = 2


class Scene:
    """What the validation needs of one scene."""

    def __init__(self, name, kind, passes, desc, reference, fitted=None):
        self.name, self.kind = name, kind
        #: The scene description with each material's fit (``--fit``), None without.
        self.fitted = fitted
        self.passes, self.desc, self.reference = passes, desc, reference[..., :3]
        index = np.rint(np.nan_to_num(passes["Material Index"])).astype(np.int64)
        self.index = index[..., 0] if index.ndim == 3 else index
        self.materials = [m for m in desc.materials if m.scatters and (self.index == m.index).any()]
        self.mask = np.isin(self.index, [m.index for m in self.materials])

    def error(self, image, mask=None) -> float:
        from sss_lab.core.study import metrics

        r = metrics.compare_images(image[..., :3], self.reference, self.mask if mask is None else mask, box=BOX)
        return float("nan") if r["rel_rmse"] is None else float(r["rel_rmse"])


def _fit(data, fit_samples: int, fit_pass_samples: int, methods, log) -> object:
    """``data.desc`` with each material's fit, made as ``calibrate`` makes it (``benchmarks/fit.py``'s
    cached render and passes of the scene just loaded, and its ``fit_like_calibrate`` for
    ``methods``: with ``calibrate``'s second render, up to its ``MAX_SAMPLES`` within its budget,
    for the fits the held-out check refuses)."""
    import bpy

    from benchmarks import fit as fit_bench
    from sss_lab.core.study.fit import BUDGET, MAX_SAMPLES

    cache = os.path.join(fit_bench.ROOT, "out", "fidelity_cache", "fit")
    os.makedirs(cache, exist_ok=True)
    scene = bpy.context.scene  # the suite's scene as load_scene built, prepared and baked it
    noisy, render_cpu = fit_bench.render_reference(
        scene, cache, samples=fit_samples, seed=fit_bench.FIT_SEED, fingerprint=data.fingerprint, log=log
    )
    passes, desc, passes_cpu = fit_bench.render_fit_passes(scene, data.fingerprint, fit_pass_samples, cache, log)
    made = fit_bench.fit_like_calibrate(
        scene,
        data.fingerprint,
        passes,
        desc,
        noisy,
        tuple(methods),
        samples=fit_samples,
        max_samples=max(MAX_SAMPLES, fit_samples),
        budget=BUDGET,
        cache=cache,
        options={},
        log=lambda _line: None,
        render_cpu=render_cpu,
        passes_cpu=passes_cpu,
    )
    if made["more"] is not None:
        log(f"  fit: refused fits, {made['more']['why']}")
    for line in made["problems"]:
        log(f"  fit: {line}")
    fits: dict = {}
    for r in made["results"]:
        fits.setdefault(r.material, {})[r.technique] = r.params
    return fit_bench.carried(data.desc, fits)


def _fidelity_scenes(names, log, fit=None):
    from benchmarks.fidelity import run as fidelity
    from benchmarks.fidelity import scenes as suite

    out = []
    for name in names or list(suite.SCENES):
        log(f"{name}: loading (fidelity suite)")
        data = fidelity.load_scene(name, log=log)
        fitted = _fit(data, *fit, log) if fit else None
        out.append(Scene(name, data.kind, data.passes, data.desc, data.reference, fitted))
    return out


def _sample_scenes(names, args, log):
    import subprocess

    import bpy

    from sss_lab.blender.reference_cache import cached_reference, scene_fingerprint
    from sss_lab.blender.render_passes import render_passes
    from sss_lab.core.pipeline import sequence
    from sss_lab.core.scene import exr

    names = list(names or SAMPLE_SCENES)
    work = os.path.join(args.cache, "blends")
    os.makedirs(work, exist_ok=True)
    subprocess.run(
        [sys.executable, os.path.join(ROOT, "sample_blends", "build_scenes.py"), *names, "--out", work],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    out = []
    for name in names:
        log(f"{name}: rendering (sample scene)")
        bpy.ops.wm.open_mainfile(filepath=os.path.join(work, f"{name}.blend"), load_ui=False)
        scene = bpy.context.scene
        fp = scene_fingerprint(scene)
        ref, _, _ = cached_reference(
            scene,
            os.path.join(args.cache, name),
            samples=args.reference_samples,
            seed=0,
            resolution=None,
            method=None,
            log=log,
            fingerprint=fp,
        )
        folder = os.path.join(args.cache, name, "passes")
        written = render_passes(scene, folder, samples=args.pass_samples, seed=7, overwrite=True, log=None)
        path = next(p for p in written if p.endswith(".exr"))
        kind = "back-lit" if "backlit" in name else "diffusion"  # the sample scenes' own classes
        out.append(Scene(name, kind, exr.read_passes(path), sequence.load_scene(path), ref))
    return out


def _fastest(fn, repeat):
    """(result, CPU seconds of the fastest of ``repeat`` calls): process CPU time, all threads,
    which other jobs on a shared machine disturb far less than the wall clock."""
    best, result = float("inf"), None
    for _ in range(repeat):
        start = time.process_time()
        result = fn()
        best = min(best, time.process_time() - start)
    return result, best


def _in_turn(fns, repeat) -> list:
    """CPU seconds of the fastest of ``repeat`` calls of each of ``fns`` (None: not timed), called
    in turn, so that a change in the shared machine's load touches them alike."""
    best = [float("inf") if fn is not None else None for fn in fns]
    for _ in range(repeat):
        for k, fn in enumerate(fns):
            if fn is None:
                continue
            start = time.process_time()
            fn()
            best[k] = min(best[k], time.process_time() - start)
    return best


def _chosen_run(plan, passes, desc):
    """The one technique and rung ``plan`` chose for every material it computes, run by itself
    (what auto's run would cost if its choice were free); None when it chose several."""
    from sss_lab.core.pipeline import apply as core_apply
    from sss_lab.core.pipeline import auto

    if len(plan.plans) != 1 or any(c.chosen == auto.NONE for c in plan.choices):
        return None
    (run,) = plan.plans
    t, options = auto.technique_of(run), auto.options_of(run)
    return lambda: core_apply.apply(passes, desc, t, **options)


def _reference(m: dict, priciest: str):
    """The most expensive technique at its default quality on the scene's larger passes."""
    from sss_lab.core.pipeline import apply as core_apply

    big, big_desc = m["big"]
    return lambda: core_apply.apply(big, big_desc, priciest)


def upscaled(passes, desc, k: int):
    """The passes repeated ``k`` x ``k`` per pixel and the camera ``k`` times finer: the same view
    at ``k`` times the resolution, for timing at a size where the techniques' work dominates."""
    from sss_lab.core.scene.exr import Passes

    if k == 1:
        return passes, desc
    arrays = {n: np.repeat(np.repeat(passes[n], k, axis=0), k, axis=1) for n in passes}
    cam = desc.camera
    camera = dataclasses.replace(cam, width_px=cam.width_px * k, height_px=cam.height_px * k)
    return Passes(arrays), dataclasses.replace(desc, camera=camera)


def measure(scene: Scene, techniques, repeat: int, time_scale: int = 1, rungs: bool = True) -> dict:
    """Errors (scene and per material) of no SSS and each technique at default quality and, with
    ``rungs``, at every other rung ``core.pipeline.auto.variants`` lists (its quality ladder, and without
    its energy stage); their times on the passes at ``time_scale`` x the resolution, and the
    features of every material."""
    from sss_lab.core.pipeline import apply as core_apply
    from sss_lab.core.pipeline import auto

    images = {auto.NONE: scene.passes["Combined"]}
    seconds = {auto.NONE: 0.0}
    big, big_desc = upscaled(scene.passes, scene.desc, time_scale)
    for t in techniques:
        try:
            core_apply.plan(scene.passes, scene.desc, t)
        except KeyError:  # its passes are missing on this scene
            continue
        for name, options in (auto.variants(t) if rungs else {t: {}}).items():
            layers = core_apply.apply(scene.passes, scene.desc, t, **options)
            images[name] = layers[core_apply.layer_names(t)[0]] if layers else scene.passes["Combined"]
            _, seconds[name] = _fastest(lambda t=t, o=options: core_apply.apply(big, big_desc, t, **o), repeat)
    every = {n: scene.error(img) for n, img in images.items()}
    errors = {n: e for n, e in every.items() if n == auto.NONE or n in techniques}
    fitted_errors = {}
    if scene.fitted is not None:  # each technique the scene's materials carry a fit for, with its fits
        have = {t for m in scene.fitted.materials for t in m.fit}
        for t in errors:
            if t not in have:
                continue
            layers = core_apply.apply(scene.passes, scene.fitted, t)
            fitted_errors[t] = scene.error(layers[core_apply.layer_names(t)[0]] if layers else scene.passes["Combined"])
    # Each candidate's work on this scene (pixels x samples, from its plan): the model's cost unit.
    unit = auto.Model({n: (1.0, 1.0, 0.0) for n in images})
    work = {}
    ran = [t for t in techniques if t in images]
    for c in auto.choose(big, big_desc, model=unit, techniques=ran, rungs=rungs).choices:
        for k in c.candidates:
            if k.excluded is None and k.name != auto.NONE:
                work[k.name] = work.get(k.name, 0.0) + k.work
    per_material = []
    for m in scene.materials:
        mask = scene.index == m.index
        f = auto.features(scene.passes, scene.desc, m)
        per_material.append((f, {t: scene.error(img, mask) for t, img in images.items()}))
    timings = [(t, work[t], seconds[t]) for t in work if t in seconds]
    out = {
        "errors": errors,
        "variant_errors": every,
        "seconds": seconds,
        "materials": per_material,
        "timings": timings,
        "big": (big, big_desc),
    }
    if scene.fitted is not None:
        out["fitted_errors"] = fitted_errors
        out["big_fitted"] = upscaled(scene.passes, scene.fitted, time_scale)
    return out


#: The choosers validated side by side (the same measurements, the same machine load): ``auto`` with
#: every rung a candidate (``--auto-rungs``), and ``auto`` learnt on the techniques' default qualities
#: alone (the default of ``apply --methods auto``).
CHOOSERS = ("auto", "techniques_only")


def _learn(measured, names, chooser: str, techniques, command: str):
    """The model learnt on the scenes ``names``; for ``techniques_only``, on no SSS and each
    technique at its default quality only."""
    from sss_lab.core.pipeline import auto

    keep = None if chooser == "auto" else {auto.NONE, *techniques}
    samples = [
        (f, {n: e for n, e in errors.items() if keep is None or n in keep})
        for o in names
        for f, errors in measured[o]["materials"]
    ]
    timings = [x for o in names for x in measured[o]["timings"] if keep is None or x[0] in keep]
    return auto.train(samples, timings=timings, trained_on=names, command=command)


def _scored_and_timed(s: Scene, desc, big, choose_and_apply, m: dict, priciest: str, repeat: int):
    """(plan, error, (auto's, its chosen run's and the most expensive technique's seconds)):
    ``auto`` chooses on the scene's passes with ``desc`` and is scored there; then it is timed on
    ``big`` (the passes at the larger size) making the same choice (its features measured there,
    at their cost; the footprint in pixels grows with the resolution, and so may the choice), in
    turn with its chosen run alone and with the most expensive technique."""
    plan, layers = choose_and_apply(s.passes, desc)
    image = layers["SSSLab.auto.Image"] if layers else s.passes["Combined"]
    times = _in_turn(
        [
            lambda: choose_and_apply(*big, keep=plan.chosen),
            _chosen_run(plan, *big),
            _reference(m, priciest),
        ],
        repeat,
    )
    return plan, s.error(image), times


def _run_chooser(s: Scene, m: dict, model, *, techniques, max_error, repeat, priciest, rungs: bool) -> dict:
    """``auto`` with ``model`` on the held-out scene ``s`` (``rungs``: the quality ladders' rungs are
    candidates, ``--auto-rungs``): its choice, error, regret and time (its features and choice
    included), and the same with the scene's fits."""
    from sss_lab.core.pipeline import auto

    def choose_and_apply(passes, desc, keep=None):
        plan = auto.choose(
            passes, desc, max_error=max_error, model=model, techniques=techniques, keep=keep, rungs=rungs
        )
        return plan, auto.apply_auto(passes, desc, prepared=plan)

    plan, err, (t_auto, t_run, t_ref) = _scored_and_timed(s, s.desc, m["big"], choose_and_apply, m, priciest, repeat)
    best = min(m["errors"], key=m["errors"].get)
    out = {
        "error": err,
        "seconds": t_auto,
        "features_s": sum(c.features.seconds for c in plan.choices),
        "choices": {c.features.name: c.chosen for c in plan.choices},
        "predicted": {
            c.features.name: {k.name: k.predicted for k in c.candidates if k.excluded is None} for c in plan.choices
        },
        "regret": err / m["errors"][best] - 1.0,
        # Against the best of every rung as well (no SSS, each technique at every rung).
        "regret_any_rung": err / min(m["variant_errors"].values()) - 1.0,
        "reference_seconds": t_ref,
        "chosen_run_seconds": t_run,
        "time_saved": 1.0 - t_auto / t_ref if t_ref > 0 else None,
        "work": {},
        "work_auto": sum(next(k.work for k in c.candidates if k.name == c.chosen) for c in plan.choices),
    }
    for c in plan.choices:
        for k in c.candidates:
            if k.excluded is None:
                out["work"][k.name] = out["work"].get(k.name, 0.0) + k.work
    if s.fitted is not None:
        out["with_fit"] = _with_fit(s, m, choose_and_apply, priciest, repeat)
    return out


def run(
    scenes, *, techniques, repeat: int, max_error: float, time_scale: int = 1, log=print, rungs: bool = True
) -> dict:
    measured = {}
    for s in scenes:
        log(f"{s.name}: measuring")
        measured[s.name] = measure(s, techniques, repeat, time_scale, rungs)
        e = measured[s.name]["errors"]
        log("  " + ", ".join(f"{t} {v:.4f}" for t, v in e.items()))
    # "The most expensive technique": the one with the largest total time over the scenes (always
    # run), at its default quality.
    totals = {}
    for m in measured.values():
        for t in m["errors"]:
            totals[t] = totals.get(t, 0.0) + m["seconds"][t]
    priciest = max(totals, key=totals.get)
    choosers = CHOOSERS if rungs else CHOOSERS[:1]
    rows = []
    for s in scenes:
        others = [o.name for o in scenes if o.name != s.name]
        m = measured[s.name]
        best = min(m["errors"], key=m["errors"].get)
        ran = {}
        for chooser in choosers:
            model = _learn(measured, others, chooser, techniques, "leave-one-scene-out")
            ran[chooser] = _run_chooser(
                s,
                m,
                model,
                techniques=techniques,
                max_error=max_error,
                repeat=repeat,
                priciest=priciest,
                rungs=rungs and chooser == "auto",
            )
        a = ran["auto"]
        rows.append(
            {
                "scene": s.name,
                "work": a.pop("work"),
                "work_auto": a.pop("work_auto"),
                "kind": s.kind,
                "errors": m["errors"],
                "variant_errors": m["variant_errors"],
                "seconds": m["seconds"],
                "auto": {k: a[k] for k in ("error", "seconds", "features_s", "choices", "predicted")},
                "best": best,
                "regret": a["regret"],
                "regret_any_rung": a["regret_any_rung"],
                "most_expensive": priciest,
                "time_saved": a["time_saved"],
                "reference_seconds": a["reference_seconds"],
                "chosen_run_seconds": a["chosen_run_seconds"],
                "features": [f.to_dict() for f, _ in m["materials"]],
                "material_errors": {f.name: e for f, e in m["materials"]},
                **({"with_fit": a["with_fit"]} if "with_fit" in a else {}),
                **{c: ran[c] for c in choosers[1:]},
            }
        )
        for chooser in choosers:
            r = ran[chooser]
            log(
                f"{s.name} [{chooser}]: chose {r['choices']}: error {r['error']:.4f}, best {best} "
                f"{m['errors'][best]:.4f} (regret {r['regret']:+.1%}); {r['seconds']:.3f} s vs {priciest} "
                f"{m['seconds'][priciest]:.3f} s"
            )
            if "with_fit" in r:
                w = r["with_fit"]
                log(
                    f"{s.name} [{chooser}] with the fit: chose {w['choices']}: error {w['error']:.4f}, best"
                    f" {w['best']} {w['best_error']:.4f} (regret {w['regret']:+.1%}); {w['seconds']:.3f} s"
                )
    always = {}
    for t in techniques:
        errs = [r["errors"][t] / r["errors"][r["best"]] - 1.0 for r in rows if t in r["errors"]]
        if errs:
            always[t] = {"mean_regret": statistics.mean(errs), "median_regret": statistics.median(errs)}
    # The shipped model is learnt without the suite's held-out third (benchmarks/fidelity/scenes.py
    # held_out), which stays out of every tuning decision.
    from benchmarks.fidelity.scenes import held_out

    learnt_on = [s.name for s in scenes if not held_out(s.name)]
    full = _learn(measured, learnt_on, "auto", techniques, "python -m benchmarks.auto --write-model")
    summary = {
        "scenes": len(rows),
        **_chooser_summary(rows, lambda r: r, max_error),
        "most_expensive": priciest,
        "total_seconds": {**totals, "auto": sum(r["auto"]["seconds"] for r in rows)},
        "always_one_technique": always,
    }
    for chooser in choosers[1:]:
        summary[chooser] = _chooser_summary(rows, lambda r, c=chooser: {**r[c], "auto": r[c]}, max_error)
    return {"rows": rows, "summary": summary, "model": full}


def _chooser_summary(rows, row_of, max_error: float) -> dict:
    """Regret and time saved of one chooser over the rows (``row_of(row)``: its ``auto``, ``regret``,
    ``time_saved`` and, with the fit, ``with_fit``), the oracles' time saved, and the fit's."""
    picked = [row_of(r) for r in rows]
    t_auto = sum(p["auto"]["seconds"] for p in picked)
    t_max = sum(p["reference_seconds"] for p in picked)
    out = {
        **_regret_and_time([p["regret"] for p in picked], [p["time_saved"] for p in picked], t_auto, t_max),
        "time_saved_total_separate": 1.0 - t_auto / sum(r["seconds"][r["most_expensive"]] for r in rows),
        **_choice_cost(picked),
        "mean_regret_any_rung": statistics.mean(p["regret_any_rung"] for p in picked),
        "oracle_time_saved_total": _oracle_saved(rows, max_error, lambda r: r["errors"]),
    }
    if all("with_fit" in p for p in picked):
        fitted = [{**r, "with_fit": p["with_fit"]} for r, p in zip(rows, picked, strict=True)]
        out["with_fit"] = _fit_summary(fitted, max_error)
    return out


def _choice_cost(picked) -> dict:
    """Over the scenes where auto ran one technique and rung for every material it computed (timed
    by itself in turn with auto and the reference): the time that run alone saves against the
    reference (auto's choice free), auto's, and auto's mean cost over it per scene (its features,
    choice and plan)."""
    one = [p for p in picked if p.get("chosen_run_seconds") is not None]
    if not one:
        return {}
    t_ref = sum(p["reference_seconds"] for p in one)
    t_run = sum(p["chosen_run_seconds"] for p in one)
    t_auto = sum(p["auto"]["seconds"] if "auto" in p else p["seconds"] for p in one)
    return {
        "one_run_scenes": len(one),
        "one_run_time_saved_if_the_choice_were_free": 1.0 - t_run / t_ref,
        "one_run_time_saved": 1.0 - t_auto / t_ref,
        "choice_seconds_per_scene": (t_auto - t_run) / len(one),
    }


def _oracle_saved(rows, max_error: float, errors_of) -> float | None:
    """The time a chooser knowing every choice's true error would save over the suite: per scene
    the cheapest choice (measured time; a fitted technique takes its technique's) whose error is
    within ``max_error`` of the scene's best, against the most expensive technique. What auto
    could save at best with the techniques' costs as measured."""
    t_chosen = t_max = 0.0
    for r in rows:
        errors = errors_of(r)
        best = min(errors.values())
        within = [c for c, e in errors.items() if e <= (1.0 + max_error) * best]
        t_chosen += min(r["seconds"][c.removesuffix(" fitted")] for c in within)
        t_max += r["seconds"][r["most_expensive"]]
    return 1.0 - t_chosen / t_max if t_max > 0 else None


def _regret_and_time(regrets, saved, t_auto: float, t_max: float) -> dict:
    """Mean, median and largest regret; time saved over the scenes (total) and per scene (median)."""
    return {
        "mean_regret": statistics.mean(regrets),
        "median_regret": statistics.median(regrets),
        "max_regret": max(regrets),
        "time_saved_total": 1.0 - t_auto / t_max if t_max > 0 else None,
        "time_saved_median": statistics.median(v for v in saved if v is not None),
    }


def _with_fit(s: Scene, m: dict, choose_and_apply, priciest: str, repeat: int) -> dict:
    """auto on the scene's passes with its fits (choosing by the fits' measured errors where they
    exist), scored against the lowest error of no SSS and every technique unfitted or fitted."""
    plan, err, (seconds, t_run, t_ref) = _scored_and_timed(
        s, s.fitted, m["big_fitted"], choose_and_apply, m, priciest, repeat
    )
    every = {**m["errors"], **{f"{t} fitted": e for t, e in m["fitted_errors"].items()}}
    best = min(every, key=every.get)
    return {
        "error": err,
        "seconds": seconds,
        "choices": {c.features.name: c.chosen for c in plan.choices},
        "measured": {
            c.features.name: {k.name: k.measured for k in c.candidates if k.measured is not None} for c in plan.choices
        },
        "fitted_errors": m["fitted_errors"],
        "best": best,
        "best_error": every[best],
        "regret": err / every[best] - 1.0,
        "reference_seconds": t_ref,
        "chosen_run_seconds": t_run,
        "time_saved": 1.0 - seconds / t_ref if t_ref > 0 else None,
    }


def _fit_summary(rows, max_error: float) -> dict:
    """Regret and time saved with the fit, and always one fitted technique's regret (against the
    same best, unfitted or fitted)."""
    fit = [r["with_fit"] for r in rows]
    regrets = [w["regret"] for w in fit]
    t_auto = sum(w["seconds"] for w in fit)
    t_max = sum(w["reference_seconds"] for w in fit)
    always = {}
    for t in sorted({t for w in fit for t in w["fitted_errors"]}):
        errs = [w["fitted_errors"][t] / w["best_error"] - 1.0 for w in fit if t in w["fitted_errors"]]
        always[t] = {"mean_regret": statistics.mean(errs), "median_regret": statistics.median(errs)}
    return {
        **_regret_and_time(regrets, [w["time_saved"] for w in fit], t_auto, t_max),
        "time_saved_total_separate": 1.0 - t_auto / sum(r["seconds"][r["most_expensive"]] for r in rows),
        **_choice_cost(fit),
        "total_seconds": t_auto,
        "always_one_fitted_technique": always,
        "oracle_time_saved_total": _oracle_saved(
            rows,
            max_error,
            lambda r: {**r["errors"], **{f"{t} fitted": e for t, e in r["with_fit"]["fitted_errors"].items()}},
        ),
    }


def sweep(scenes, technique: str, parameter: str, values, log=print) -> dict:
    """``technique`` at its default quality with ``parameter`` set to each of ``values`` on every
    scene: per value the errors, and over the suite the median of error / no-SSS error (the
    share of the no-SSS error left) and the scenes where it is worse than no SSS."""
    from sss_lab.core.pipeline import apply as core_apply

    per_value = {}
    for v in values:
        rows = {}
        for s in scenes:
            layers = core_apply.apply(s.passes, s.desc, technique, **{parameter: v})
            image = layers[core_apply.layer_names(technique)[0]] if layers else s.passes["Combined"]
            rows[s.name] = {"error": s.error(image), "no_sss": s.error(s.passes["Combined"]), "kind": s.kind}
        ratios = [r["error"] / r["no_sss"] for r in rows.values()]
        per_value[str(v)] = {
            "scenes": rows,
            "median_left": statistics.median(ratios),
            "mean_left": statistics.mean(ratios),
            "by_kind": {
                k: statistics.median(r["error"] / r["no_sss"] for r in rows.values() if r["kind"] == k)
                for k in sorted({r["kind"] for r in rows.values()})
            },
            "worse_than_no_sss": sorted(n for n, r in rows.items() if r["error"] > r["no_sss"]),
        }
        log(
            f"{technique} {parameter}={v}: median share of the no-SSS error left {per_value[str(v)]['median_left']:.3f}"
            f" (by kind {per_value[str(v)]['by_kind']}); worse than no SSS on {per_value[str(v)]['worse_than_no_sss']}"
        )
    return per_value


def quality_oracle(rows, *, max_error: float, log=print) -> dict:
    """What a chooser knowing every true error could save if it chose each technique's quality too:
    from ``run``'s measurements of every candidate (each rung of each technique's quality ladder,
    the ladder ``compare`` sweeps, and each diffusion's rungs without its energy stage,
    ``core.pipeline.auto.variants``), per scene the cheapest whose error is within ``max_error`` of the best
    one's, against the most expensive technique at its default (largest total time over the scenes),
    over the suite; the same with the default qualities only, for comparison."""
    from sss_lab.core.pipeline import auto

    def saved(keep) -> tuple[float, dict]:
        chosen, t_chosen, t_max = {}, 0.0, 0.0
        for r in rows:
            pool = {n: e for n, e in r["variant_errors"].items() if n != auto.NONE and keep(r, n)}
            best = min(pool.values())
            pick = min((n for n, e in pool.items() if e <= (1.0 + max_error) * best), key=lambda n: r["seconds"][n])
            chosen[r["scene"]] = pick
            t_chosen += r["seconds"][pick]
            t_max += r["seconds"][r["most_expensive"]]
        return 1.0 - t_chosen / t_max, chosen

    with_quality, chosen = saved(lambda r, n: True)
    defaults, _ = saved(lambda r, n: n in r["errors"])
    priciest = rows[0]["most_expensive"]
    log(
        f"knowing every true error: choosing the quality and the energy stage too saves {with_quality:.0%}, "
        f"the techniques at their defaults {defaults:.0%}, against always {priciest}"
    )
    return {
        "most_expensive": priciest,
        "oracle_time_saved_total": with_quality,
        "oracle_time_saved_total_defaults": defaults,
        "chosen": chosen,
        "scenes": [
            {
                "scene": r["scene"],
                "variants": [
                    {"variant": n, "default": n in r["errors"], "error": e, "seconds": r["seconds"][n]}
                    for n, e in r["variant_errors"].items()
                    if n != auto.NONE
                ],
            }
            for r in rows
        ],
    }


def _print_summary(title: str, s: dict, always: dict, suffix: str) -> None:
    print(
        f"{title}: regret mean {s['mean_regret']:+.1%}, median {s['median_regret']:+.1%}, max {s['max_regret']:+.1%};"
        f" time saved against the most expensive technique {s['time_saved_total']:.0%} (total),"
        f" {s['time_saved_median']:.0%} (median); knowing every true error, at most {s['oracle_time_saved_total']:.0%}"
    )
    for t, v in always.items():
        print(f"  always {t}{suffix}: mean regret {v['mean_regret']:+.1%}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.auto", description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help="scenes (default: all of the source)")
    parser.add_argument("--source", choices=("fidelity", "samples"), default=None, help="default: fidelity if present")
    parser.add_argument("--max-error", type=float, default=None, help="auto's margin (default: core.pipeline.auto's)")
    parser.add_argument("--repeat", type=int, default=7, help="timed runs per case, fastest kept (default 7)")
    parser.add_argument(
        "--time-scale",
        type=int,
        default=4,
        help="time every run on the passes at this many times the scenes' resolution (default 4: 512 px for"
        " 128 px scenes; at 128 px a technique takes a few ms and fixed costs dominate)",
    )
    parser.add_argument("--reference-samples", type=int, default=512, help="samples of the sample scenes' references")
    parser.add_argument("--pass-samples", type=int, default=64, help="samples of the sample scenes' passes")
    parser.add_argument("--cache", default=os.path.join(tempfile.gettempdir(), "sss_lab_auto_bench"))
    parser.add_argument(
        "--write-model", action="store_true", help="store the model learnt on all scenes but the held-out third"
    )
    parser.add_argument(
        "--sweep-transmission",
        help="comma-separated transmission scales of the combined technique to score on every scene (its default)",
    )
    parser.add_argument(
        "--fit",
        action="store_true",
        help="also validate with each scene fitted as calibrate fits it (benchmarks/fit.py's render and passes)",
    )
    parser.add_argument("--fit-samples", type=int, default=32, help="with --fit: samples of the fit's render")
    parser.add_argument("--fit-pass-samples", type=int, default=16, help="with --fit: samples of the fit's passes")
    parser.add_argument(
        "--fit-methods",
        help="with --fit: the techniques fitted, comma-separated (default: every technique that has a fit;"
        " calibrate's own default is burley,combined)",
    )
    parser.add_argument(
        "--quality-oracle",
        action="store_true",
        help="also report what a chooser knowing every true error could save choosing each technique's rung (its"
        " quality ladder, and each diffusion without its energy stage) too",
    )
    parser.add_argument(
        "--no-rungs",
        action="store_true",
        help="measure and choose among the techniques at their default qualities only (auto before its rungs)",
    )
    parser.add_argument("--out", default=RESULTS)
    args = parser.parse_args(argv)
    import bpy

    from benchmarks._common import write_results
    from sss_lab.core.pipeline import auto
    from sss_lab.core.techniques.registry import TECHNIQUES

    try:  # timed on one thread: an idle thread pool spins, and its CPU time would count against the next run
        import numba

        numba.set_num_threads(1)
    except ImportError:
        pass
    source = args.source
    if source is None:
        source = "fidelity" if os.path.isdir(os.path.join(ROOT, "benchmarks", "fidelity")) else "samples"
    start = time.perf_counter()
    if args.fit and source != "fidelity":
        parser.error("--fit: only with the fidelity suite (the fit's render is cached by benchmarks/fit.py)")
    from sss_lab.core.pipeline.fit_params import FIT_PARAMETERS

    methods = args.fit_methods.split(",") if args.fit_methods else list(FIT_PARAMETERS)
    unknown = [m for m in methods if m not in FIT_PARAMETERS]
    if unknown:
        parser.error(f"--fit-methods: no fit exists for {', '.join(unknown)}; expected: {', '.join(FIT_PARAMETERS)}")
    fit = (args.fit_samples, args.fit_pass_samples, methods) if args.fit else None
    scenes = (
        _fidelity_scenes(args.names, print, fit) if source == "fidelity" else _sample_scenes(args.names, args, print)
    )
    max_error = auto.DEFAULT_MAX_ERROR if args.max_error is None else args.max_error
    swept = None
    if args.sweep_transmission:
        values = [float(v) for v in args.sweep_transmission.split(",")]
        swept = sweep(scenes, "combined", "transmission_scale", values)
    if args.quality_oracle and args.no_rungs:
        parser.error("--quality-oracle: needs the rungs measured (without --no-rungs)")
    out = run(
        scenes,
        techniques=list(TECHNIQUES),
        repeat=args.repeat,
        max_error=max_error,
        time_scale=args.time_scale,
        rungs=not args.no_rungs,
    )
    qualities = quality_oracle(out["rows"], max_error=max_error) if args.quality_oracle else None
    command = " ".join(["python -m benchmarks.auto", *(argv if argv is not None else sys.argv[1:])])
    model = dataclasses.replace(out.pop("model"), command=command)
    if args.write_model:
        auto.save_model(model)
        print(f"Saved: {auto.MODEL_PATH}")
    data = {
        "definition": __doc__.split("\n\n")[2].strip(),
        "source": source,
        "max_error": max_error,
        "time_scale": args.time_scale,
        "fit": None if fit is None else dict(zip(("samples", "pass_samples", "methods"), fit, strict=True)),
        "command": command,
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "note": "shared, loaded 2-core machine"},
        "blender": bpy.app.version_string,
        "total_seconds": time.perf_counter() - start,
        "summary": out["summary"],
        "model_all_scenes": model.to_dict(),
        "scenes": out["rows"],
    }
    if swept is not None:
        data["combined_transmission_scale_sweep"] = swept
    if qualities is not None:
        data["quality_oracle"] = qualities
    write_results(args.out, data)
    s = out["summary"]
    _print_summary(f"{s['scenes']} scenes, leave-one-scene-out", s, s["always_one_technique"], "")
    if "with_fit" in s:
        w = s["with_fit"]
        _print_summary("with the fit (best of unfitted and fitted)", w, w["always_one_fitted_technique"], " fitted")
    if "techniques_only" in s:
        o = s["techniques_only"]
        _print_summary("the same run, auto choosing among the techniques' defaults only", o, {}, "")
        if "with_fit" in o:
            _print_summary("  with the fit", o["with_fit"], {}, "")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
