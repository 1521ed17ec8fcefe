"""EEVEE against Cycles on the fidelity suite, as authored and after ``match-eevee``:
``.venv/bin/python -m benchmarks.eevee [NAMES] [--into docs/fidelity.md]``.

For every scene of the suite (``benchmarks/fidelity``: its stored references, Cycles random walk
at 1024 samples x 2 seeds, and its cached passes, Cycles without scattering at 64 samples):

1. EEVEE with and without scattering, the scene's own EEVEE settings, at the suite's size
   (``blender.eevee.cached_eevee``): its image and its SSS effect on Cycles' image without
   scattering (Cycles' passes + EEVEE with - EEVEE without), each scored with the suite's measure
   (relative RMSE over the subsurface pixels after 2 x 2 box downsampling,
   ``benchmarks/fidelity/run.py``); *removed* = 1 - error / the no-SSS error, for the SSS effect
   the share of Cycles' SSS effect EEVEE reproduces (docs/references.md §18);
2. ``match-eevee`` as a user runs it (``blender.match_eevee.match_eevee``: its own Cycles render of
   the view at ``--match-samples``, its passes, its EEVEE frames), then EEVEE again, scored the
   same way against the stored reference it never saw;
3. the techniques' figures of the suite's last run (``benchmarks/results/fidelity.json``) beside.

Writes ``benchmarks/results/eevee.json`` and, with ``--into``, a section of docs/fidelity.md
(after its kept-sections line). Nothing here knows a scene by name. EEVEE renders through EGL
(software OpenGL on a machine without a GPU): a few seconds a frame at the suite's size.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results", "eevee.json")
FIDELITY = os.path.join(ROOT, "benchmarks", "results", "fidelity.json")
HEADING = "EEVEE against Cycles, as authored and matched"


def _removed(err, none):
    return None if err is None or not none else 1.0 - err / none


def run_scene(name: str, args, cache: str, log) -> dict:
    import bpy
    import numpy as np

    from benchmarks.fidelity import run as fidelity
    from sss_lab.blender.eevee import cached_eevee
    from sss_lab.blender.match_eevee import MatchSettings, match_eevee
    from sss_lab.blender.reference_cache import scene_fingerprint

    data = fidelity.load_scene(name, log=log)
    scene = bpy.context.scene  # the suite's scene as load_scene built and baked it
    r = scene.render
    size = (r.resolution_y * r.resolution_percentage // 100, r.resolution_x * r.resolution_percentage // 100)
    if size != tuple(data.passes.shape):
        raise RuntimeError(f"{name}: the open scene is not the size of the passes the suite loaded")
    c_none = data.passes["Combined"]
    none = data.score(c_none)["rel_rmse"]

    def eevee(sss: bool):
        return cached_eevee(
            scene, cache, samples=None, resolution=None, sss=sss, fingerprint=scene_fingerprint(scene), log=log
        )

    def scored(on, off) -> dict:
        effect = np.array(c_none, np.float32)
        effect[..., :3] += on[0][..., :3] - off[0][..., :3]
        image = data.score(on[0])["rel_rmse"]
        sss = data.score(effect)["rel_rmse"]
        return {
            "image_error": image,
            "image_removed": _removed(image, none),
            "effect_error": sss,
            "effect_removed": _removed(sss, none),
            "seconds": on[1],
            "seconds_without_sss": off[1],
        }

    start = time.perf_counter()
    off = eevee(False)
    authored = scored(eevee(True), off)
    match_start = time.perf_counter()
    result = match_eevee(
        scene, MatchSettings(cycles_samples=args.match_samples, pass_samples=args.match_pass_samples), log=log
    )
    match_s = time.perf_counter() - match_start
    matched = scored(eevee(True), off)
    return {
        "scene": name,
        "kind": data.kind,
        "no_sss_error": none,
        "noise_floor": data.noise_floor,
        "eevee_samples": scene.eevee.taa_render_samples,
        "authored": authored,
        "matched": matched,
        "match": result["materials"],
        "match_seconds": match_s,
        "seconds": time.perf_counter() - start,
    }


def _techniques(path: str) -> dict:
    """{scene: {technique: removed at default quality}} of the suite's last run."""
    if not os.path.isfile(path):
        return {}
    with open(path, encoding="utf-8") as f:
        data = json.load(f)
    out = {}
    for s in data.get("scenes", []):
        rows = [r for r in s.get("rows", []) if r.get("default") and r["technique"] != "none"]
        out[s["scene"]] = {r["technique"]: r.get("removed") for r in rows}
    return out


def _pct(v) -> str:
    return "n/a" if v is None else f"{100 * v:+.0f}%"


def _median_of(techniques: dict, group: list[dict], technique: str):
    vals = [
        techniques[r["scene"]][technique] for r in group if techniques.get(r["scene"], {}).get(technique) is not None
    ]
    return statistics.median(vals) if vals else None


def _ramp(result: dict) -> str:
    """Whether the match kept the view angle's ramp (``set_view_factor``) on the scene's materials."""
    kept = [m.get("view") for m in result.get("match", {}).values() if not m.get("skipped")]
    return "yes" if any(kept) else ("no" if kept else "-")


def _less(a, b) -> bool:
    return a is not None and b is not None and a < b


def markdown(results: list[dict], techniques: dict, command: str) -> str:
    names = sorted({t for s in techniques.values() for t in s})
    lines = [
        "EEVEE (Blender's real-time renderer, the scene's own EEVEE settings) on the suite's scenes, scored"
        " against the stored Cycles references: *image*, its picture as it renders; *SSS effect*, EEVEE with"
        " scattering minus without, on Cycles' image without scattering (the share of Cycles' SSS effect it"
        " reproduces, docs/references.md §18); *matched*: after `match-eevee` (its own 64-sample Cycles render of"
        " the view; `blender/match_eevee.py`: the width of EEVEE's gather, a Base Color gain, the view angle's"
        " ramp where it helps (*view ramp*), the baked thickness on EEVEE's Thickness socket). Each as the"
        " share of the no-SSS error removed; the techniques at their default quality from the suite's last"
        " run beside.",
        "",
        f"Generated by `{command}`.",
        "",
        "| scene | kind | EEVEE image | EEVEE SSS effect | matched image | matched SSS effect | view ramp | "
        + " | ".join(names)
        + " |",
        "|---|---|---|---|---|---|---|" + "---|" * len(names),
    ]
    for r in results:
        a, m = r["authored"], r["matched"]
        tech = techniques.get(r["scene"], {})
        lines.append(
            f"| {r['scene']} | {r['kind']} | {_pct(a['image_removed'])} | {_pct(a['effect_removed'])} |"
            f" {_pct(m['image_removed'])} | {_pct(m['effect_removed'])} | {_ramp(r)} | "
            + " | ".join(_pct(tech.get(t)) for t in names)
            + " |"
        )
    for kind in sorted({r["kind"] for r in results}):
        group = [r for r in results if r["kind"] == kind]

        def med(key, which, group=group):
            vals = [r[which][key] for r in group if r[which][key] is not None]
            return statistics.median(vals) if vals else None

        lines.append(
            f"| **median, {kind}** ({len(group)}) | | {_pct(med('image_removed', 'authored'))} |"
            f" {_pct(med('effect_removed', 'authored'))} | {_pct(med('image_removed', 'matched'))} |"
            f" {_pct(med('effect_removed', 'matched'))} | | "
            + " | ".join(_pct(_median_of(techniques, group, t)) for t in names)
            + " |"
        )
    worse = [r["scene"] for r in results if _less(r["matched"]["effect_removed"], r["authored"]["effect_removed"])]
    lines += [
        "",
        "Scenes where the match reproduces less of Cycles' SSS effect than EEVEE as authored:"
        f" {', '.join(worse) or 'none'}.",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.eevee", description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help="fidelity scenes (default: all)")
    parser.add_argument("--match-samples", type=int, default=64, help="match-eevee's Cycles samples (default 64)")
    parser.add_argument("--match-pass-samples", type=int, default=16, help="match-eevee's pass samples (default 16)")
    parser.add_argument("--cache", default=os.path.join(ROOT, "out", "eevee_cache"))
    parser.add_argument("--out", default=RESULTS)
    parser.add_argument("--into", help="a Markdown file to put the table in (a section after the kept-sections line)")
    args = parser.parse_args(argv)
    from benchmarks.fidelity import scenes as suite

    names = args.names or list(suite.SCENES)
    command = "python -m benchmarks.eevee" + ("" if not args.names else " " + " ".join(args.names))
    if args.into:
        command += f" --into {args.into}"

    def log(line):
        print(line, flush=True)

    os.makedirs(args.cache, exist_ok=True)
    start = time.perf_counter()
    results = []
    with tempfile.TemporaryDirectory():
        for name in names:
            log(f"{name}:")
            results.append(run_scene(name, args, args.cache, lambda line: None))
            r = results[-1]
            log(
                f"  EEVEE SSS effect {_pct(r['authored']['effect_removed'])} -> matched"
                f" {_pct(r['matched']['effect_removed'])} (image {_pct(r['authored']['image_removed'])} ->"
                f" {_pct(r['matched']['image_removed'])}), {r['seconds']:.0f} s"
            )
    import bpy

    out = {
        "definition": __doc__,
        "command": command,
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "blender": bpy.app.version_string,
        "total_seconds": time.perf_counter() - start,
        "scenes": results,
    }
    from sss_lab.core.base.files import write_text

    write_text(args.out, json.dumps(out, indent=1, default=str))
    log(f"Saved: {args.out}")
    body = markdown(results, _techniques(FIDELITY), command)
    print(body)
    if args.into:
        from benchmarks.fidelity.pairs import write_into

        write_into(args.into, HEADING, body)
        log(f"Saved: {args.into}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
