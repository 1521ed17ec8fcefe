"""Fit to Cycles, measured on the fidelity suite: ``.venv/bin/python -m benchmarks.fit [SCENE ...]``.

For every scene of the fidelity suite (``benchmarks/fidelity``, or of ``--scenes-module`` with
``--store``: its builders, stored references and metric, nothing duplicated here):

1. **frame A**, the scene as the suite builds it (``fidelity.run.load_scene``: the converged
   reference, the mean of two 1024-sample seeds, and the passes at 64 samples, seed 7);
2. **the fit, as** ``calibrate`` **makes it**: Cycles random walk of the same view at
   ``--fit-samples`` (16-64) with a seed of its own (2, neither the reference's 0 and 1 nor the
   passes' 7, whose noise it would share) through the same render function ``calibrate`` uses, its
   own passes at ``--fit-pass-samples`` (seed 2), and ``core.study.fit.fit_scene`` with ``calibrate``'s
   options, for each technique of ``--methods``;
3. each technique at its default quality, unfitted and with the fit, on the suite's passes,
   scored against the converged reference with the suite's metric (relative RMSE over the
   subsurface pixels after 2 x 2 box downsampling; *removed* = 1 - error / no-SSS error): does
   a fit made on a noisy image hold against the converged one;
4. **frame B** of the same asset (``scenes.frame_b``: camera turned 20 degrees about the
   subsurface objects and 10 % closer, lights turned -15 degrees), with its own stored reference
   (``references.STORE_B``, 2 x ``references.SAMPLES_B`` samples): the fit of frame A carried unchanged by material
   name, scored the same way.

The fit's cost: the CPU time (process time, all of Cycles' threads; steadier than the wall clock
on this shared machine) of the fit's random-walk render plus the fit itself (every technique of
``--methods``, after an untimed first run of each, which compiles or loads its Numba kernels once
per installation), with and without the fit's own passes render, as a share of **the reference
render it stands in for: Cycles random walk of the same view at 1024 samples**
(``--timing-samples``; the suite's reference is two such renders), rendered and timed here the
same way (seed 3); also for what ``calibrate`` fits by default (Burley and combined), its passes
included.

Per kind (diffusion / back-lit), the median over the scenes of the share removed by the best
technique (per scene, the technique with the lowest error, unfitted or fitted: the suite's
"best"), and by each technique alone. Renders are cached in ``out/fidelity_cache`` (with the
CPU seconds they took). Writes ``benchmarks/results/fit.json`` and prints a table.

``--keep-refused`` keeps the fits that fail their held-out check (``core.study.fit``'s
``heldout_check=False``: the training blocks' values, a note says so) and scores them the same
way, into ``benchmarks/results/fit_keep_refused.json``: whether what the check refuses on the
noisy render would have been better against the converged references, on both frames.

``--oracle`` fits on frame A's own passes and converged reference (no fit render, no held-out
check, no ridge), into ``benchmarks/results/fit_oracle.json``: the least error per scene that the
fit's parameters (gain per channel, d's scale, the light from behind's scale and lengths) can
reach on the blocks it fits, scored as above; frame B shows how such a fit carries. A scene
whose fitted error is near its oracle's is at the limit of the fit's model, not of its noise.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import platform
import shlex
import statistics
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results", "fit.json")
#: ``--keep-refused``'s results: never calibrate's fit, so never in RESULTS.
REFUSED = os.path.join(ROOT, "benchmarks", "results", "fit_keep_refused.json")
#: ``--oracle``'s results: the fit's model fitted on the truth, a bound on what the fit can do.
ORACLE = os.path.join(ROOT, "benchmarks", "results", "fit_oracle.json")
#: Seeds of the fit's render and passes, and of the render timed for the cost: none of the
#: references' (0, 1) nor the scored passes' (7).
FIT_SEED = 2
TIMING_SEED = 3
#: Seeds of ``calibrate``'s one-sample pilot and its second render (``_more_samples``).
MORE_SEED = 4
PILOT_SEED = 5


def _median(values):
    v = [x for x in values if x is not None and x == x]
    return statistics.median(v) if v else None


def render_reference(scene, cache: str, *, samples: int, seed: int, fingerprint: str, log):
    """Cycles random walk of the scene's view (``calibrate``'s render function, through the
    reference cache): (RGBA image, CPU seconds of the render as measured when it was made)."""
    from benchmarks.fidelity import scenes as suite
    from sss_lab.blender.reference_cache import cached_reference

    key = hashlib.sha256(f"{fingerprint}:{samples}:{seed}".encode()).hexdigest()[:20]
    meta = os.path.join(cache, f"cpu_{key}.json")
    start = time.process_time()
    image, _wall, cached = cached_reference(
        scene,
        cache,
        samples=samples,
        seed=seed,
        resolution=suite.RESOLUTION,
        method=None,
        log=log,
        fingerprint=fingerprint,
    )
    return image, _cpu_seconds(meta, time.process_time() - start, cached)


def _cpu_seconds(meta: str, measured: float, cached: bool) -> float:
    """The CPU seconds of a cached render as recorded in ``meta`` when it was made; ``measured``
    (recorded now) when it was made by this call."""
    if cached and os.path.isfile(meta):
        with open(meta, encoding="utf-8") as fh:
            return float(json.load(fh)["cpu_seconds"])
    with open(meta, "w", encoding="utf-8") as fh:
        json.dump({"cpu_seconds": measured}, fh)
    return measured


def render_fit_passes(scene, fingerprint: str, samples: int, cache: str, log):
    """The fit's own passes (seed ``FIT_SEED``), cached with the CPU seconds they took."""
    from benchmarks.fidelity import run as fidelity

    key = hashlib.sha256(f"fit:{fingerprint}:{fidelity.thickness_digest(scene)}:{FIT_SEED}".encode()).hexdigest()[:20]
    meta = os.path.join(cache, f"{key}_{samples}", "cpu.json")
    start = time.process_time()
    passes, desc, _wall, cached = fidelity.cached_passes(scene, key, samples, cache, log, seed=FIT_SEED)
    return passes, desc, _cpu_seconds(meta, time.process_time() - start, cached)


def _unfitted(desc):
    return dataclasses.replace(desc, materials=tuple(dataclasses.replace(m, fit={}) for m in desc.materials))


def carried(desc, fits: dict):
    """``desc`` with each material's fit taken from ``fits`` (material name -> fit)."""
    return dataclasses.replace(
        desc, materials=tuple(dataclasses.replace(m, fit=fits.get(m.name, {})) for m in desc.materials)
    )


def _score(data, desc, methods) -> dict:
    """{technique: relative RMSE} of no SSS ("none") and each technique at its default quality on
    the suite's passes of ``data`` with the fits of ``desc``."""
    from sss_lab.core.pipeline import apply as core_apply

    out = {"none": data.score(data.passes["Combined"])["rel_rmse"]}
    for t in methods:
        layers = core_apply.apply(data.passes, desc, t)
        image = layers[core_apply.layer_names(t)[0]] if layers else data.passes["Combined"]
        out[t] = data.score(image)["rel_rmse"]
    return out


def _removed(errors: dict) -> dict:
    none = errors["none"]
    return {t: (1.0 - e / none if none else None) for t, e in errors.items() if t != "none"}


def run_scene(name: str, args, log) -> dict:
    import bpy

    from benchmarks.fidelity import frame_b, references
    from benchmarks.fidelity import run as fidelity
    from sss_lab.blender.calibrate import DEFAULT_TECHNIQUES
    from sss_lab.core.pipeline import apply as core_apply

    methods = tuple(args.methods.split(","))
    cache = os.path.join(args.cache, "fit")
    os.makedirs(cache, exist_ok=True)
    module = fidelity.load_scenes_module(args.scenes_module)
    store = args.store or references.STORE
    a = fidelity.load_scene(name, scenes=module, cache=args.cache, store=store, log=log)
    scene = bpy.context.scene  # the suite's scene as built, prepared and baked by load_scene
    if args.oracle:  # fitted on what it is scored against: the suite's passes and converged reference
        noisy, fit_passes, fit_desc = a.reference, a.passes, a.desc
    else:
        noisy, fit_render_cpu = render_reference(
            scene, cache, samples=args.fit_samples, seed=FIT_SEED, fingerprint=a.fingerprint, log=log
        )
        _, timing_cpu = render_reference(
            scene, cache, samples=args.timing_samples, seed=TIMING_SEED, fingerprint=a.fingerprint, log=log
        )
        fit_passes, fit_desc, passes_cpu = render_fit_passes(scene, a.fingerprint, args.fit_pass_samples, cache, log)
    for t in methods:  # untimed: a technique's first run compiles (or loads) its Numba kernels, once per install
        core_apply.apply(fit_passes, _unfitted(fit_desc), t)
    # calibrate's options unless asked otherwise (to measure another setting of the fit).
    options = {k: v for k, v in (("box", args.box), ("regularization", args.regularization)) if v is not None}
    if args.keep_refused or args.oracle:
        options["heldout_check"] = False
    if args.oracle and args.regularization is None:
        options["regularization"] = 0.0
    start = time.perf_counter()
    made = fit_like_calibrate(
        scene,
        a.fingerprint,
        fit_passes,
        fit_desc,
        noisy,
        methods,
        samples=args.fit_samples,
        max_samples=None if args.oracle else args.max_samples,
        budget=args.budget,
        cache=cache,
        options=options,
        log=log,
        render_cpu=None if args.oracle else fit_render_cpu,
        passes_cpu=None if args.oracle else passes_cpu,
        more_seed=args.more_seed,
    )
    fit_s = time.perf_counter() - start
    results, problems, fit_cpu_by, more = (
        made["results"],
        made["problems"],
        made["fit_cpu_s_by_technique"],
        made["more"],
    )
    fit_cpu = sum(fit_cpu_by.values())
    default_cpu = sum(fit_cpu_by.get(t, 0.0) for t in DEFAULT_TECHNIQUES)
    fits: dict = {}
    for r in results:
        fits.setdefault(r.material, {})[r.technique] = r.params
    row: dict = {
        "scene": name,
        "kind": a.kind,
        "held_out": bool(getattr(module.SCENES[name], "held_out", False)),
        "noise_floor": {"A": a.noise_floor},
        "fits": [r.to_dict() for r in results],
        "problems": problems,
    }
    unfitted = _unfitted(a.desc)
    row["A"] = {"unfitted": _score(a, unfitted, methods), "fitted": _score(a, carried(a.desc, fits), methods)}
    if not args.no_frame_b:
        b = fidelity.load_scene(name, scenes=frame_b, cache=args.cache, store=references.STORE_B, log=log)
        row["noise_floor"]["B"] = b.noise_floor
        row["B"] = {
            "unfitted": _score(b, _unfitted(b.desc), methods),
            "fitted": _score(b, carried(b.desc, fits), methods),
        }
    for frame in ("A", "B"):
        if frame not in row:
            continue
        f = row[frame]
        for kind in ("unfitted", "fitted"):
            f[f"removed_{kind}"] = _removed(f[kind])
        both = {
            **{f"{t} unfitted": e for t, e in f["unfitted"].items() if t != "none"},
            **{f"{t} fitted": e for t, e in f["fitted"].items() if t != "none"},
        }
        f["best"] = min(both, key=both.get)
        f["best_unfitted"] = min(methods, key=lambda t: f["unfitted"][t])
        f["removed_best"] = 1.0 - both[f["best"]] / f["unfitted"]["none"]
        f["removed_best_unfitted"] = f["removed_unfitted"][f["best_unfitted"]]
    if args.oracle:
        return row
    # Cost: CPU seconds of the fit against those of the render it stands in for.
    renders, fits_all, fits_default = fit_render_cpu, fit_cpu, default_cpu
    if more is not None:  # the pilot, and the second render and fit when they were made
        renders += more["pilot_cpu_s"] + more.get("render_cpu_s", 0.0)
        fits_all += sum(more.get("fit_cpu_s_by_technique", {}).values())
        fits_default += sum(more.get("fit_cpu_s_by_technique", {}).get(t, 0.0) for t in DEFAULT_TECHNIQUES)
        row["more_samples"] = more
    row["cost"] = {
        "fit_render_cpu_s": fit_render_cpu,
        "fit_passes_cpu_s": passes_cpu,
        "fit_cpu_s": fit_cpu,
        "fit_cpu_s_by_technique": fit_cpu_by,
        "fit_wall_s": fit_s,  # the fits, with the pilot and the second render where they were made
        "stands_in_for_cpu_s": timing_cpu,
        "share": (renders + fits_all) / timing_cpu,
        "share_with_passes": (renders + fits_all + passes_cpu) / timing_cpu,
        # What ``calibrate`` fits by default (burley, combined), its passes included.
        "share_calibrate_default": (renders + fits_default + passes_cpu) / timing_cpu,
    }
    return row


def fit_like_calibrate(
    scene,
    fingerprint: str,
    passes,
    desc,
    noisy,
    methods,
    *,
    samples: int,
    max_samples: int | None,
    budget: float,
    cache: str,
    options: dict,
    log,
    render_cpu: float | None,
    passes_cpu: float | None,
    more_seed: int = MORE_SEED,
) -> dict:
    """The fits ``calibrate`` makes of ``methods`` on ``passes`` (and their scene description
    ``desc``) and the ``samples``-sample render ``noisy``, one technique at a time (each one's CPU
    seconds), and then ``calibrate``'s second render for the fits the held-out check refused (when
    ``max_samples`` exceeds ``samples``): the one-sample pilot (seed ``PILOT_SEED``),
    ``core.study.fit.more_samples``' decision on CPU seconds (``calibrate`` decides on wall seconds; on
    this shared machine CPU time is the steadier measure; what ``calibrate`` fits by default,
    ``DEFAULT_TECHNIQUES``, counts as the fit's time), and when it says so ``max_samples`` -
    ``samples`` more samples (seed ``more_seed``), the mean of the two renders, and the refused
    (material, technique) fitted again on it, replacing their refusals. Renders cached in ``cache``.

    Returns {"results", "problems" (lines), "fit_cpu_s_by_technique", "more": None or what the
    second render did ("extra", "why", "pilot_cpu_s", "render_cpu_s", "fit_cpu_s_by_technique",
    "fits")}."""
    from sss_lab.blender.calibrate import DEFAULT_TECHNIQUES
    from sss_lab.core.study.fit import after_second_fit, fit_scene, mean_render, more_samples, refused_pairs

    results, problems, refused, by = [], [], [], {}
    for t in methods:
        cpu0 = time.process_time()
        got, missed = fit_scene(
            passes, _unfitted(desc), noisy, techniques=(t,), samples=samples, log=log, refused=refused, **options
        )
        by[t] = time.process_time() - cpu0
        results += got
        problems += missed
    out: dict = {"results": results, "problems": problems, "fit_cpu_s_by_technique": by, "more": None}
    if not refused or max_samples is None or max_samples <= samples or render_cpu is None or passes_cpu is None:
        return out
    default_cpu = sum(by.get(t, 0.0) for t in DEFAULT_TECHNIQUES)
    _, pilot_cpu = render_reference(scene, cache, samples=1, seed=PILOT_SEED, fingerprint=fingerprint, log=log)
    extra, why = more_samples(
        samples=samples,
        max_samples=max_samples,
        spent_s=render_cpu + passes_cpu + default_cpu + pilot_cpu,
        render_s=render_cpu,
        pilot_s=pilot_cpu,
        fit_s=default_cpu,
        budget=budget,
    )
    log(f"  {len(refused)} fit(s) refused by the held-out check; {why}")
    more: dict = {"extra": extra, "why": why, "pilot_cpu_s": pilot_cpu}
    out["more"] = more
    if not extra:
        problems.append(f"not rendered again for the refused fits: {why}")
        return out
    image, more["render_cpu_s"] = render_reference(
        scene, cache, samples=extra, seed=more_seed, fingerprint=fingerprint, log=log
    )
    total = samples + extra
    mean = mean_render(noisy, samples, image, extra)
    again = refused_pairs(refused)
    redo, redo_problems, more["fit_cpu_s_by_technique"] = [], [], {}
    for t in sorted({t for _m, t in again}):
        cpu0 = time.process_time()
        got, missed = fit_scene(
            passes,
            _unfitted(desc),
            mean,
            techniques=(t,),
            samples=total,
            log=log,
            only={p for p in again if p[1] == t},
            **options,
        )
        more["fit_cpu_s_by_technique"][t] = time.process_time() - cpu0
        redo += got
        redo_problems += missed
    more["fits"] = [{"material": m, "technique": t} for m, t in sorted(again)]
    out["results"] = results + redo  # the refused pairs have no result of the first fit
    out["problems"] = after_second_fit(problems, refused, redo_problems)
    return out


def summarize(rows, methods) -> dict:
    out = {}
    from benchmarks.fidelity.run import kind_groups

    for kind, sel in kind_groups(rows):
        k = {"scenes": len(sel)}
        for frame in ("A", "B"):
            have = [r for r in sel if frame in r]
            if not have:
                continue
            k[frame] = {
                "median_removed_best_unfitted": _median([r[frame]["removed_best_unfitted"] for r in have]),
                "median_removed_best": _median([r[frame]["removed_best"] for r in have]),
                "median_removed_fitted_by_technique": {
                    t: _median([r[frame]["removed_fitted"][t] for r in have]) for t in methods
                },
                "median_removed_unfitted_by_technique": {
                    t: _median([r[frame]["removed_unfitted"][t] for r in have]) for t in methods
                },
            }
        out[kind] = k
    if any("cost" not in r for r in rows):  # --oracle: no fit render, no cost
        return out
    out["cost"] = {
        "median_share": _median([r["cost"]["share"] for r in rows]),
        "max_share": max(r["cost"]["share"] for r in rows),
        "median_share_with_passes": _median([r["cost"]["share_with_passes"] for r in rows]),
        "median_share_calibrate_default": _median([r["cost"]["share_calibrate_default"] for r in rows]),
        "max_share_calibrate_default": max(r["cost"]["share_calibrate_default"] for r in rows),
    }
    return out


def summary_markdown(summary: dict, command: str) -> str:
    """The medians of ``summarize`` as a Markdown table: per group of scenes (each kind, and its
    held-out scenes and the rest apart), the share of the no-SSS error the best technique removes
    unfitted and with the fit, on frame A and (with the fit of A) on frame B."""

    def pct(v):
        return "—" if v is None else f"{100 * v:.0f} %"

    lines = [
        "The share of the no-SSS error removed by the best technique (unfitted or fitted, per scene), median"
        " over the scenes: the fit made as `calibrate` makes it (a 32-sample Cycles render of the same view),"
        " scored against the stored references; frame B is the same asset seen and lit otherwise, with the fit"
        " of frame A. *held out*: the scenes kept out of every fit and tuning decision"
        " (`benchmarks/fidelity/scenes.py` `held_out`).",
        "",
        f"Generated by `{command}`.",
        "",
        "| scenes | n | frame A unfitted | frame A with the fit | frame B unfitted | frame B with the fit of A |",
        "|---|---|---|---|---|---|",
    ]
    for group, k in summary.items():
        if group == "cost":
            continue
        a, b = k.get("A", {}), k.get("B", {})
        lines.append(
            f"| {group} | {k['scenes']} | {pct(a.get('median_removed_best_unfitted'))} |"
            f" {pct(a.get('median_removed_best'))} | {pct(b.get('median_removed_best_unfitted'))} |"
            f" {pct(b.get('median_removed_best'))} |"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.fit", description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help="fidelity scenes (default: all)")
    parser.add_argument("--fit-samples", type=int, default=32, help="samples of the render the fit is made on (16-64)")
    parser.add_argument("--fit-pass-samples", type=int, default=16, help="samples of the fit's passes (calibrate's)")
    parser.add_argument(
        "--max-samples",
        type=int,
        default=None,
        help="calibrate's samples in all for the fits its held-out check refuses (default: calibrate's, 64;"
        " --fit-samples: never render again)",
    )
    parser.add_argument(
        "--budget", type=float, default=None, help="calibrate's cost budget for rendering again (default: its own)"
    )
    parser.add_argument(
        "--more-seed",
        type=int,
        default=MORE_SEED,
        help=f"seed of the second render for refused fits (default {MORE_SEED}; another shows how much the"
        " outcome owes to that render's noise)",
    )
    parser.add_argument(
        "--timing-samples", type=int, default=1024, help="samples of the render the fit stands in for (timed)"
    )
    parser.add_argument("--methods", default="ssss,burley,combined,sta")
    parser.add_argument("--box", type=int, default=None, help="the fit's block size (default: calibrate's)")
    parser.add_argument(
        "--regularization", type=float, default=None, help="the fit's ridge weight (default: core.study.fit's)"
    )
    parser.add_argument(
        "--keep-refused",
        action="store_true",
        help="keep the fits that fail the held-out check (to measure what it refuses against the converged"
        f" references; written to {os.path.basename(REFUSED)} unless --out is given)",
    )
    parser.add_argument(
        "--oracle",
        action="store_true",
        help="fit on frame A's own passes and converged reference, without held-out check or ridge: the"
        f" least error the fit's parameters can reach (written to {os.path.basename(ORACLE)} unless --out is given)",
    )
    parser.add_argument("--no-frame-b", action="store_true", help="frame A only")
    parser.add_argument(
        "--scenes-module",
        help="a module with SCENES built the suite's way (default: the suite; frame B is the suite's only)",
    )
    parser.add_argument("--store", default=None, help="folder of the scenes' stored references (default: the suite's)")
    parser.add_argument("--cache", default=os.path.join(ROOT, "out", "fidelity_cache"))
    parser.add_argument("--out", default=None, help=f"results file (default {os.path.relpath(RESULTS, ROOT)})")
    parser.add_argument(
        "--into", help="a Markdown file to put the summary table in (a section after the fidelity runner's marker)"
    )
    args = parser.parse_args(argv)
    from sss_lab.core.study.fit import BUDGET, MAX_SAMPLES

    if args.max_samples is None:
        args.max_samples = max(MAX_SAMPLES, args.fit_samples)
    if args.budget is None:
        args.budget = BUDGET
    if args.out is None:
        args.out = ORACLE if args.oracle else REFUSED if args.keep_refused else RESULTS
    import bpy

    from benchmarks._common import write_results

    def log(line):
        print(line, flush=True)

    if args.scenes_module:
        args.no_frame_b = True  # the suite's frame B exists for the suite's scenes only
    from benchmarks.fidelity.run import load_scenes_module

    names = args.names or list(load_scenes_module(args.scenes_module).SCENES)
    methods = tuple(args.methods.split(","))
    start = time.perf_counter()
    rows = []
    for name in names:
        log(f"{name}:")
        rows.append(run_scene(name, args, log))
        r = rows[-1]
        for frame in ("A", "B"):
            if frame in r:
                f = r[frame]
                log(
                    f"  {frame}: no SSS {f['unfitted']['none']:.3f}; "
                    + ", ".join(f"{t} {f['unfitted'][t]:.3f} -> {f['fitted'][t]:.3f}" for t in methods)
                    + f"; best {f['best']} removes {f['removed_best']:.0%} (unfitted {f['removed_best_unfitted']:.0%})"
                )
        if "cost" in r:
            log(
                f"  fit cost {r['cost']['share']:.1%} of {args.timing_samples} spp"
                f" ({r['cost']['share_with_passes']:.1%} with its passes)"
            )
    summary = summarize(rows, methods)
    data = {
        "command": "python -m benchmarks.fit " + " ".join(argv if argv is not None else sys.argv[1:]),
        "definition": __doc__.split("\n\n", 1)[1].strip(),
        "settings": {k: v for k, v in vars(args).items() if k not in ("names", "cache", "out")},
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "note": "shared, loaded 2-core machine"},
        "blender": bpy.app.version_string,
        "total_seconds": time.perf_counter() - start,
        "summary": summary,
        "scenes": rows,
    }
    write_results(args.out, data)
    if args.into:
        from benchmarks.fidelity.pairs import write_into

        given = argv if argv is not None else sys.argv[1:]
        command = shlex.join(["python", "-m", "benchmarks.fit", *given])
        write_into(args.into, "After calibrate", summary_markdown(summary, command))
        log(f"Saved: {args.into}")
    for kind, k in summary.items():
        if kind == "cost":
            continue
        for frame in ("A", "B"):
            if frame in k:
                f = k[frame]
                log(
                    f"{kind} ({k['scenes']}) frame {frame}: median removed, best technique"
                    f" {f['median_removed_best_unfitted']:.0%}"
                    f" unfitted -> {f['median_removed_best']:.0%} with the fit; fitted by technique "
                    + ", ".join(f"{t} {v:.0%}" for t, v in f["median_removed_fitted_by_technique"].items())
                )
    if "cost" not in summary:
        return 0
    c = summary["cost"]
    log(
        f"fit cost: median {c['median_share']:.1%} (max {c['max_share']:.1%}) of a {args.timing_samples}-sample render,"
        f" {c['median_share_with_passes']:.1%} with its passes; calibrate's default (burley, combined, its passes"
        f" included) median {c['median_share_calibrate_default']:.1%}, max {c['max_share_calibrate_default']:.1%}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
