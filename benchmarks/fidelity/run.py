"""Score every technique on every scene of the fidelity suite against the stored references.

``make fidelity`` (= ``.venv/bin/python -m benchmarks.fidelity.run``) writes
``benchmarks/results/fidelity.json``, ``docs/fidelity.md`` (tables) and
``docs/images/fidelity_grid.png`` (pictures), and prints the summary. ``run()`` returns the same
results to a script (per scene, per technique and quality), so that other work (fitting a
material to Cycles, a new technique) is judged on the same scenes the same way.

Per scene, exactly the same steps whatever the scene (nothing here knows a scene by name; a
scene module built with the suite's conventions is scored identically, ``--scenes-module``):

1. build the scene, give it pass indices, take its fingerprint and load its stored reference
   (``references.py``; a scene that no longer matches fails loudly). The reference is the mean
   of the two stored seeds (2 x ``references.SAMPLES`` samples);
2. bake thickness with the bake's defaults (for STA), render the passes twice: at the default
   ``PASS_SAMPLES`` (what a user renders, ``compare``'s default) and at ``HIGH_SAMPLES``;
3. apply every technique at each quality of ``QUALITIES`` to both sets of passes.

Two runs of the same code give the same figures to the bit, whether the passes are rendered
again (``--no-cache``) or read from the cache: the scenes' meshes are numbered the same way on
every build (``sample_blends/build_scenes.py`` ``_canonical``), so the thickness bake, the cache
key and Cycles' passes are too (docs/references.md §13 says what varied before).

Definitions (every figure of the outputs uses them):

- **relative RMSE** (``core/study/metrics.py``, what ``compare`` reports): the root mean square of the
  difference from the reference over the pixels of the subsurface materials (Material Index of a
  scattering material) and the three linear RGB channels, after 2 x 2 box downsampling of both
  images (a block counts when all four pixels are subsurface), divided by the reference's mean
  over the same pixels.
- **removed**: 1 - error / (error of no SSS), both on the default passes: the share of the error
  that missing SSS causes which the technique takes away (negative: it made the image worse).
- **bias** and **pass noise**: the error split into what stays with noise-free passes (the
  technique's own approximation, plus the reference's small noise) and what the passes' Monte
  Carlo noise adds. The technique is applied to passes at ``PASS_SAMPLES`` (error e) and at
  ``HIGH_SAMPLES`` (error e_h); independent errors add in quadrature and the passes' noise
  variance falls as 1 / samples, so e^2 = bias^2 + noise^2 and e_h^2 = bias^2 + noise^2 x
  PASS_SAMPLES / HIGH_SAMPLES, which gives noise^2 = (e^2 - e_h^2) / (1 - PASS_SAMPLES /
  HIGH_SAMPLES) and bias^2 = e^2 - noise^2 (each clipped at 0).
- **noise floor**: the relative RMSE between the two stored seeds (``compare``'s definition, the
  error of one 1024-sample reference against another). **reference noise**: half of it, the
  expected error of the two-seed mean against the converged image (the difference of two seeds
  has twice the variance of one, the mean half of it): differences smaller than it are not
  measurable, and "worse than no SSS" means worse by more than it.
- **energy**: per subsurface material and channel, the sum of the image over the material's
  pixels divided by the reference's sum (1 = the same light; for the technique and no SSS).
- **time**: seconds of the technique's ``core.pipeline.apply`` on the default passes (one run, NumPy, a
  loaded 2-core machine: indicative only; ``make bench`` measures speed).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import json
import os
import shutil
import statistics
import sys
import tempfile
import time

import numpy as np

from . import references

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RESULTS = os.path.join(ROOT, "benchmarks", "results", "fidelity.json")
TABLE = os.path.join(ROOT, "docs", "fidelity.md")
GRID = os.path.join(ROOT, "docs", "images", "fidelity_grid.png")
CACHE = os.path.join(ROOT, "out", "fidelity_cache")

#: Passes as a user renders them (``compare``'s default) and nearly noise-free.
PASS_SAMPLES = 64
HIGH_SAMPLES = 256
#: Seeds of the passes: not those of the references (0 and 1), whose noise they would share.
PASS_SEED = 7
BOX = 2

#: Each technique's qualities: its default first (``core/pipeline/mapping.py``), then higher ones. A
#: registered technique not listed here runs at its default only.
QUALITIES: dict[str, tuple[dict, ...]] = {
    "sta": ({}, {"falloff": "map"}),
    "ssss": ({}, {"n_taps": 25}, {"weighting": "screen"}),
    "burley": ({}, {"n_samples": 64}, {"n_samples": 128}),
}


def quality_label(technique: str, quality: dict) -> str:
    from sss_lab.core.techniques.registry import TECHNIQUES

    label = TECHNIQUES[technique].label
    if not quality:
        return f"{label} (default)"
    return label + " " + ", ".join(f"{k.replace('n_', '')}={v}" for k, v in quality.items())


def load_scenes_module(name: str | None):
    if name is None:
        from . import scenes

        return scenes
    return importlib.import_module(name)


def thickness_digest(scene) -> str:
    """A hash of what the passes depend on beside the scene's fingerprint, for their cache key:
    the baked thickness of every mesh (STA's AOV) and how each mesh is numbered (its edges' and
    its faces' vertices, in order). The fingerprint reads the faces in a canonical order, while
    Cycles follows the numbering to the last bits: passes rendered from the same mesh numbered
    otherwise are not read back for it (docs/references.md §13)."""
    h = hashlib.sha256()
    for obj in sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name):
        mesh = obj.data
        h.update(obj.name.encode())
        for items, prop in ((mesh.edges, "vertices"), (mesh.loops, "vertex_index"), (mesh.polygons, "loop_total")):
            width = 2 if prop == "vertices" else 1
            numbers = np.empty(len(items) * width, dtype=np.int32)
            items.foreach_get(prop, numbers)
            h.update(numbers.tobytes())
        attr = mesh.attributes.get("Thickness")
        if attr is None:
            continue
        values = np.empty(len(attr.data) * 4, dtype=np.float32)
        attr.data.foreach_get("color", values)
        h.update(values.tobytes())
    return h.hexdigest()[:16]


def cached_passes(scene, key: str, samples: int, cache: str | None, log, *, seed: int = PASS_SEED):
    """The passes at ``samples`` (Cycles seed ``seed``), from ``cache`` when rendered before for the
    same ``key`` (scene, bake and seed) and samples. Returns (Passes, SceneDescription, seconds to
    render, from cache)."""
    from sss_lab.blender.render_passes import render_passes
    from sss_lab.core.pipeline import sequence
    from sss_lab.core.scene import exr
    from sss_lab.core.techniques.registry import TECHNIQUES

    folder = os.path.join(cache or tempfile.mkdtemp(prefix="sss_lab_fidelity_"), f"{key}_{samples}")
    exr_path = os.path.join(folder, "passes_0001.exr")
    meta = os.path.join(folder, "seconds.json")
    cached = os.path.isfile(exr_path) and os.path.isfile(meta)
    if cached:
        with open(meta, encoding="utf-8") as fh:
            seconds = json.load(fh)["seconds"]
    else:
        shutil.rmtree(folder, ignore_errors=True)
        start = time.perf_counter()
        written = render_passes(
            scene,
            folder,
            techniques=tuple(TECHNIQUES),
            samples=samples,
            seed=seed,
            frames=[1],
            overwrite=True,
            log=None,
        )
        seconds = time.perf_counter() - start
        exr_path = next(p for p in written if p.endswith(".exr"))
        with open(meta, "w", encoding="utf-8") as fh:
            json.dump({"seconds": seconds}, fh)
    log(f"  passes {samples} spp seed {seed}: {'cached' if cached else f'{seconds:.1f} s'}")
    passes = exr.read_passes(exr_path)
    desc = sequence.load_scene(exr_path)
    if cache is None:
        shutil.rmtree(os.path.dirname(folder), ignore_errors=True)
    return passes, desc, seconds, cached


class SceneData:
    """Everything a scorer needs for one scene: the reference (mean of two seeds) and its noise
    floor, the passes at both sample counts with their scene descriptions, the masks."""

    def __init__(self, name, kind, reference, seeds, passes, desc, passes_high, desc_high, timings, fingerprint):
        self.name, self.kind = name, kind
        self.reference, self.seeds = reference, seeds
        self.passes, self.desc = passes, desc
        self.passes_high, self.desc_high = passes_high, desc_high
        self.timings, self.fingerprint = timings, fingerprint
        index = np.rint(np.nan_to_num(passes["Material Index"])).astype(np.int64)
        self.index = index[..., 0] if index.ndim == 3 else index
        self.materials = [m for m in desc.materials if m.scatters]
        self.mask = np.isin(self.index, [m.index for m in self.materials])
        self.noise_floor = self.score(seeds[1], against=seeds[0])["rel_rmse"]
        self.reference_noise = 0.5 * self.noise_floor

    def score(self, image, *, against=None) -> dict:
        from sss_lab.core.study import metrics

        return metrics.compare_images(image, self.reference if against is None else against, self.mask, box=BOX)

    def energy(self, image) -> dict:
        """Per scattering material: the image's light over the reference's, per channel."""
        out = {}
        for m in self.materials:
            sel = self.index == m.index
            if not sel.any():
                continue
            ref = self.reference[sel][:, :3].astype(np.float64).sum(axis=0)
            img = np.nan_to_num(np.asarray(image)[sel][:, :3].astype(np.float64)).sum(axis=0)
            out[m.name] = [round(float(a / b), 4) if b > 0 else None for a, b in zip(img, ref, strict=True)]
        return out


def load_scene(
    name: str,
    *,
    scenes=None,
    cache: str | None = CACHE,
    store: str = references.STORE,
    log=print,
    thickness_source: str | None = None,
):
    """Build scene ``name`` (of the module ``scenes``, default the suite), check and load its
    reference, bake, render (or reuse) the passes: a ``SceneData``."""
    from . import scenes as suite

    module = scenes or suite
    table = module.SCENES
    start = time.perf_counter()
    scene = suite.build(name, table)
    suite.prepare(scene)
    fp = references.fingerprint(scene)
    seed0, seed1, _entry = references.load(name, fp, store=store)
    suite.bake(scene, source=thickness_source)
    key = hashlib.sha256(f"{fp}:{thickness_digest(scene)}:{PASS_SEED}".encode()).hexdigest()[:20]
    timings = {"build_and_bake_s": time.perf_counter() - start}
    passes, desc, timings["passes_s"], _ = cached_passes(scene, key, PASS_SAMPLES, cache, log)
    passes_high, desc_high, timings["passes_high_s"], _ = cached_passes(scene, key, HIGH_SAMPLES, cache, log)
    reference = 0.5 * (seed0[..., :3] + seed1[..., :3])
    return SceneData(
        name, table[name].kind, reference, (seed0, seed1), passes, desc, passes_high, desc_high, timings, fp
    )


#: Techniques applied once already in this process: their compiled kernels are loaded.
_WARM: set[tuple] = set()


def _apply(passes, desc, technique, quality):
    from sss_lab.core.pipeline import apply as core_apply

    # Untimed first call of each technique and quality: it compiles (or loads) the Numba kernels of
    # that quality's code path and builds its one-off tables (STA's medium falloff: the walk's).
    key = (technique, tuple(sorted((k, repr(v)) for k, v in quality.items())))
    if key not in _WARM:
        core_apply.apply(passes, desc, technique, **quality)
        _WARM.add(key)
    start = time.perf_counter()
    layers = core_apply.apply(passes, desc, technique, **quality)
    seconds = time.perf_counter() - start
    if not layers:
        return passes["Combined"][..., :3], seconds
    return layers[core_apply.layer_names(technique)[0]][..., :3], seconds


def split_error(error: float, error_high: float) -> tuple[float, float]:
    """(bias, pass noise) from the errors with the default and the high-sample passes."""
    from sss_lab.core.study.metrics import split_error as split

    return split(error, error_high, PASS_SAMPLES, HIGH_SAMPLES)


def score_scene(data: SceneData, *, qualities=None, log=print) -> dict:
    """Every technique at every quality on ``data``: the figures of the module docstring."""
    if qualities is None:
        from sss_lab.core.techniques.registry import TECHNIQUES

        qualities = {t: QUALITIES.get(t, ({},)) for t in TECHNIQUES}
    none = data.score(data.passes["Combined"])["rel_rmse"]
    none_bias, none_noise = split_error(none, data.score(data.passes_high["Combined"])["rel_rmse"])
    rows = [
        {
            "technique": "none",
            "quality": {},
            "label": "no SSS",
            "default": True,
            "rel_rmse": none,
            "bias": none_bias,
            "pass_noise": none_noise,
            "removed": 0.0,
            "energy": data.energy(data.passes["Combined"]),
            "apply_s": 0.0,
        }
    ]
    images = {"no SSS": data.passes["Combined"][..., :3]}
    for technique, ladder in qualities.items():
        for i, quality in enumerate(ladder):
            image, seconds = _apply(data.passes, data.desc, technique, quality)
            high, _ = _apply(data.passes_high, data.desc_high, technique, quality)
            err = data.score(image)["rel_rmse"]
            bias, noise = split_error(err, data.score(high)["rel_rmse"])
            label = quality_label(technique, quality)
            rows.append(
                {
                    "technique": technique,
                    "quality": quality,
                    "label": label,
                    "default": i == 0,
                    "rel_rmse": err,
                    "bias": bias,
                    "pass_noise": noise,
                    "removed": 1.0 - err / none if none else None,
                    "energy": data.energy(image),
                    "apply_s": round(seconds, 3),
                }
            )
            if i == 0:
                images[technique] = image
            log(f"  {label}: {err:.4f} (bias {bias:.4f}), removed {rows[-1]['removed']:+.0%}")
    return {
        "scene": data.name,
        "kind": data.kind,
        "mappings": mapping_rows(data, log=log),
        "fingerprint": data.fingerprint,
        "noise_floor": data.noise_floor,
        "reference_noise": data.reference_noise,
        "pixels": int(data.mask.sum()),
        "materials": [
            {"name": m.name, "method": m.method, "radius": list(m.radius), "base_color": list(m.base_color)}
            for m in data.materials
        ],
        "timings": {k: round(v, 2) for k, v in data.timings.items()},
        "rows": rows,
        "_images": images,
    }


def mapping_rows(data: SceneData, *, techniques=("ssss", "burley"), log=print) -> list[dict]:
    """Each mapping from the Principled BSDF to d (``core.pipeline.mapping.MAPPINGS``) for each subsurface
    method of the scene, with the scattering techniques at their default quality."""
    from sss_lab.core.pipeline.mapping import MAPPINGS

    rows = []
    for method in sorted({m.method for m in data.materials}):
        for technique in techniques:
            for name in MAPPINGS[method]:
                image, _ = _apply(data.passes, data.desc, technique, {"mapping": {method: name}})
                err = data.score(image)["rel_rmse"]
                rows.append({"method": method, "technique": technique, "mapping": name, "rel_rmse": err})
            log(
                f"  mapping {method} {technique}: "
                + ", ".join(f"{r['mapping']} {r['rel_rmse']:.4f}" for r in rows[-len(MAPPINGS[method]) :])
            )
    return rows


def summarize_mappings(results: list[dict]) -> list[dict]:
    """Per subsurface method, technique and mapping: over the scenes with that method, the median
    error and the median of the error relative to the default mapping's (the first listed)."""
    from sss_lab.core.pipeline.mapping import MAPPINGS

    out = []
    for method, names in MAPPINGS.items():
        for technique in ("ssss", "burley"):
            per_scene = {}
            for s in results:
                rows = [r for r in s.get("mappings", []) if r["method"] == method and r["technique"] == technique]
                if rows:
                    per_scene[s["scene"]] = {r["mapping"]: r["rel_rmse"] for r in rows}
            if not per_scene:
                continue
            for name in names:
                errs = [v[name] for v in per_scene.values()]
                ratios = [v[name] / v[names[0]] for v in per_scene.values() if v[names[0]]]
                out.append(
                    {
                        "method": method,
                        "technique": technique,
                        "mapping": name,
                        "default": name == names[0],
                        "scenes": sorted(per_scene),
                        "median_rel_rmse": statistics.median(errs),
                        "median_ratio_to_default": statistics.median(ratios) if ratios else None,
                        "best_on": sum(min(v, key=v.get) == name for v in per_scene.values()),
                    }
                )
    return out


def kind_groups(rows: list[dict]) -> list[tuple[str, list[dict]]]:
    """(label, rows) per scene kind, and, where a kind has held-out scenes (``scenes.held_out``),
    "<kind>, held out" and "<kind>, the rest" apart: the groups every summary reports. Rows are
    per-scene results with "kind" and "held_out"."""
    groups = []
    for kind in sorted({r["kind"] for r in rows}):
        of_kind = [r for r in rows if r["kind"] == kind]
        groups.append((kind, of_kind))
        out_of_fits = [r for r in of_kind if r.get("held_out")]
        if out_of_fits:
            groups.append((f"{kind}, held out", out_of_fits))
            groups.append((f"{kind}, the rest", [r for r in of_kind if not r.get("held_out")]))
    return [(label, group) for label, group in groups if group]


def summarize(results: list[dict]) -> dict:
    """Medians per scene kind (technique at default quality), the best technique per kind, and
    the checks of the suite's goals."""
    techniques = sorted({r["technique"] for s in results for r in s["rows"] if r["technique"] != "none"})
    out = {"kinds": {}, "worse_than_no_sss": [], "burley_vs_ssss": None, "mappings": summarize_mappings(results)}
    for kind, scenes in kind_groups(results):
        medians = {}
        for t in techniques:
            removed = [r["removed"] for s in scenes for r in s["rows"] if r["technique"] == t and r["default"]]
            if removed:
                medians[t] = statistics.median(removed)
        best_each = [max(r["removed"] for r in s["rows"] if r["default"] and r["technique"] != "none") for s in scenes]
        best = max(medians, key=medians.get) if medians else None
        out["kinds"][kind] = {
            "scenes": len(scenes),
            "median_removed_by_technique": medians,
            "best_technique": best,
            "best_technique_median_removed": medians.get(best),
            "median_of_per_scene_best_removed": statistics.median(best_each) if best_each else None,
        }
    for s in results:
        none = next(r for r in s["rows"] if r["technique"] == "none")["rel_rmse"]
        for r in s["rows"]:
            if r["technique"] != "none" and r["rel_rmse"] - none > s["reference_noise"]:
                out["worse_than_no_sss"].append(
                    {"scene": s["scene"], "label": r["label"], "rel_rmse": r["rel_rmse"], "no_sss": none}
                )
    pairs = []
    for s in results:
        d = {r["technique"]: r["rel_rmse"] for r in s["rows"] if r["default"]}
        if "burley" in d and "ssss" in d:
            pairs.append(d["burley"] / d["ssss"])
    if pairs:
        out["burley_vs_ssss"] = {
            "median_error_ratio_burley_over_ssss": statistics.median(pairs),
            "scenes_burley_better_or_equal": sum(p <= 1.0 for p in pairs),
            "scenes": len(pairs),
        }
    return out


def _grid(results: list[dict], path: str) -> None:
    from sss_lab.core.study import png

    columns = ["no SSS", *_techniques(results), "reference"]
    tiles = []
    for s in results:
        imgs = s["_images"]
        for c in columns:
            img = imgs.get(c)
            tiles.append(png.to_display(img) if img is not None else np.zeros_like(png.to_display(imgs["no SSS"])))
    png.write_png(path, png.grid(tiles, columns=len(columns)))


def _techniques(results: list[dict]) -> list[str]:
    """The techniques scored, in the order they ran."""
    out: list[str] = []
    for s in results:
        for r in s["rows"]:
            if r["technique"] != "none" and r["technique"] not in out:
                out.append(r["technique"])
    return out


def _fmt(v, pct=False):
    if v is None:
        return "–"
    return f"{v:+.0%}" if pct else f"{v:.3f}"


#: The line after which a table file holds sections other commands write
#: (``benchmarks/fidelity/pairs.py --into``): ``main`` keeps them when it writes the table again.
KEPT = "<!-- Sections below are written by other commands (benchmarks/fidelity/pairs.py); make fidelity keeps them. -->"


def kept_sections(path: str) -> str:
    """What ``path`` holds from the ``KEPT`` line on ("" when it has none or does not exist)."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except FileNotFoundError:
        return ""
    at = text.find(KEPT)
    return "" if at < 0 else text[at:]


def markdown(data: dict, grid: str = "images/fidelity_grid.png") -> str:
    techs = _techniques(data["scenes"])
    lines = [
        "# Fidelity suite results",
        "",
        f"Generated by `{data['command']}` ({data['generated_utc']}, Blender {data['blender']}, "
        f"{data['total_seconds']:.0f} s on a shared 2-core machine). Definitions: `benchmarks/fidelity/run.py`; "
        "scenes: `benchmarks/fidelity/scenes.py`; references: Cycles, the scene's own subsurface method, "
        f"{data['reference_samples']} samples x 2 seeds (mean), passes {data['pass_samples']} samples (default) "
        f"and {data['high_samples']} (for the bias).",
        "",
        "Relative RMSE over the subsurface pixels after 2 x 2 box downsampling (lower is better); "
        "*removed* = share of the no-SSS error taken away; *bias* / *noise*: the error split into what stays "
        "with noise-free passes and what the passes' noise adds (extrapolated from the two sample counts, "
        "see the definitions).",
        "",
        "## Summary (each technique at its default quality)",
        "",
        "| scenes | n | " + " | ".join(f"{t} removed (median)" for t in techs) + " | best |",
        "|---|---|" + "---|" * (len(techs) + 1),
    ]
    for kind, k in data["summary"]["kinds"].items():
        med = k["median_removed_by_technique"]
        lines.append(
            f"| {kind} | {k['scenes']} | "
            + " | ".join(_fmt(med.get(t), True) for t in techs)
            + f" | {k['best_technique']} {_fmt(k['best_technique_median_removed'], True)} |"
        )
    bvs = data["summary"]["burley_vs_ssss"]
    if bvs:
        lines += [
            "",
            f"Burley / SSSS error at default quality: median ratio {bvs['median_error_ratio_burley_over_ssss']:.3f}; "
            f"Burley better or equal on {bvs['scenes_burley_better_or_equal']} of {bvs['scenes']} scenes.",
        ]
    worse = data["summary"]["worse_than_no_sss"]
    lines += [
        "",
        "Worse than no SSS by more than the reference noise (half the two-seed noise floor): "
        + (
            "none."
            if not worse
            else "; ".join(f"{w['scene']} {w['label']} ({w['rel_rmse']:.3f} vs {w['no_sss']:.3f})" for w in worse)
        ),
        "",
        "## Per scene (default quality; bias / noise in brackets)",
        "",
        "| scene | kind | noise floor | no SSS | " + " | ".join(techs) + " |",
        "|---|---|---|---|" + "---|" * len(techs),
    ]
    for s in data["scenes"]:
        d = {r["technique"]: r for r in s["rows"] if r["default"]}

        def cell(t, d=d):
            r = d.get(t)
            if r is None:
                return "–"
            text = f"{r['rel_rmse']:.3f} ({r['bias']:.3f} / {r['pass_noise']:.3f})"
            return text if t == "none" else f"{text} {_fmt(r['removed'], True)}"

        lines.append(
            f"| {s['scene']} | {s['kind']}{' (held out)' if s.get('held_out') else ''} | {s['noise_floor']:.3f} | "
            + " | ".join(cell(t) for t in ("none", *techs))
            + " |"
        )
    lines += [
        "",
        "## Higher qualities",
        "",
        "| scene | technique | error | bias | noise | removed | apply s |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in data["scenes"]:
        for r in s["rows"]:
            if r["technique"] == "none":
                continue
            lines.append(
                f"| {s['scene']} | {r['label']} | {r['rel_rmse']:.3f} | {r['bias']:.3f} | {r['pass_noise']:.3f} |"
                f" {_fmt(r['removed'], True)} | {r['apply_s']:.2f} |"
            )
    lines += [
        "",
        "## Energy per material and channel (image / reference, R G B; default quality)",
        "",
        "| scene | material | no SSS | " + " | ".join(techs) + " |",
        "|---|---|---|" + "---|" * len(techs),
    ]
    for s in data["scenes"]:
        d = {r["technique"]: r for r in s["rows"] if r["default"]}
        for m in s["materials"]:
            cells = []
            for t in ("none", *techs):
                e = d.get(t, {}).get("energy", {}).get(m["name"])
                cells.append(" ".join(f"{v:.2f}" for v in e) if e else "–")
            lines.append(f"| {s['scene']} | {m['name']} ({m['method']}) | " + " | ".join(cells) + " |")
    lines += [
        "",
        "## The mapping from the Principled BSDF to d, per subsurface method",
        "",
        "Each mapping of `core/pipeline/mapping.py` applied to the scenes that use the method (SSSS and Burley"
        " at their "
        "default quality, default passes): median relative RMSE, median ratio to the default mapping's error "
        "(below 1 = better than the default), and on how many of those scenes it was the best.",
        "",
        "| method | technique | mapping | scenes | median error | median ratio to default | best on |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in data["summary"]["mappings"]:
        name = m["mapping"] + (" (default)" if m["default"] else "")
        lines.append(
            f"| {m['method']} | {m['technique']} | {name} | {len(m['scenes'])} | {m['median_rel_rmse']:.3f} | "
            f"{_fmt(m['median_ratio_to_default'])} | {m['best_on']} |"
        )
    lines += [
        "",
        "## Pictures",
        "",
        "Columns: no SSS, " + ", ".join(techs) + " (each at its default quality, default passes), reference; "
        "one row per scene in the order of the table.",
        "",
        f"![fidelity grid]({grid})",
        "",
    ]
    return "\n".join(lines)


def run(
    names=None,
    *,
    scenes=None,
    qualities=None,
    cache: str | None = CACHE,
    store=references.STORE,
    log=print,
    thickness_source: str | None = None,
):
    """Score ``names`` (default: every scene of ``scenes``, default the suite); returns
    {"scenes": [per-scene results], "summary": ...}. Per-scene results hold ``rows`` (one per
    technique and quality) and ``_images`` (the default-quality images, not JSON)."""
    from . import scenes as suite

    module = scenes or suite
    names = list(names or module.SCENES)
    results = []
    for name in names:
        log(f"{name}:")
        data = load_scene(name, scenes=module, cache=cache, store=store, log=log, thickness_source=thickness_source)
        result = score_scene(data, qualities=qualities, log=log)
        result["held_out"] = bool(getattr(module.SCENES[name], "held_out", False))
        result["_images"]["reference"] = data.reference
        results.append(result)
    return {"scenes": results, "summary": summarize(results)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="Score every technique on the fidelity suite (make fidelity).")
    parser.add_argument("names", nargs="*", help="scenes (default: all)")
    parser.add_argument("--scenes-module", help="a module with SCENES built the suite's way (default: the suite)")
    parser.add_argument("--store", default=references.STORE, help="folder of the stored references")
    parser.add_argument("--no-cache", action="store_true", help="render the passes again instead of reusing them")
    parser.add_argument(
        "--thickness-source",
        choices=("ao", "ray"),
        default=None,
        help="the thickness bake's source (default: the bake's default for its attribute target, ray;"
        " core/scene/thickness.py)",
    )
    parser.add_argument("--out", default=RESULTS, help=f"JSON results (default {RESULTS})")
    parser.add_argument("--table", default=TABLE, help=f"Markdown table (default {TABLE})")
    parser.add_argument("--grid", default=GRID, help=f"picture grid (default {GRID})")
    args = parser.parse_args(argv)
    import bpy

    from sss_lab.core.base.files import write_text

    module = load_scenes_module(args.scenes_module)
    start = time.perf_counter()
    out = run(
        args.names,
        scenes=module,
        cache=None if args.no_cache else CACHE,
        store=args.store,
        thickness_source=args.thickness_source,
    )
    total = time.perf_counter() - start
    data = {
        "command": "make fidelity"
        if not (args.names or args.scenes_module or args.thickness_source)
        else " ".join(["python -m benchmarks.fidelity.run", *sys.argv[1:]]),
        "generated_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "blender": bpy.app.version_string,
        "total_seconds": total,
        "reference_samples": references.SAMPLES,
        "pass_samples": PASS_SAMPLES,
        "high_samples": HIGH_SAMPLES,
        "box": BOX,
        "definitions": __doc__.split("Definitions (every figure of the outputs uses them):")[1].strip(),
        "summary": out["summary"],
        "scenes": [{k: v for k, v in s.items() if not k.startswith("_")} for s in out["scenes"]],
    }
    from benchmarks._common import write_results

    write_results(args.out, data)
    grid = os.path.relpath(os.path.abspath(args.grid), os.path.dirname(os.path.abspath(args.table)))
    kept = kept_sections(args.table)
    write_text(args.table, markdown(data, grid.replace(os.sep, "/")) + ("\n" + kept if kept else ""))
    print(f"Saved: {args.table}")
    os.makedirs(os.path.dirname(args.grid), exist_ok=True)
    _grid(out["scenes"], args.grid)
    print(f"Saved: {args.grid}")
    for kind, k in out["summary"]["kinds"].items():
        med = ", ".join(f"{t} {v:+.0%}" for t, v in k["median_removed_by_technique"].items())
        print(f"{kind} ({k['scenes']} scenes): median share of the no-SSS error removed: {med}")
    print(f"Total: {total:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
