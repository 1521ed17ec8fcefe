"""Fit to Cycles, measured: ``.venv/bin/python -m benchmarks.fit [SCENE.blend ...]``.

For each scene (default: the four sample scenes, built into a temporary folder):

1. frame A (the scene as saved): the converged reference (Cycles random walk, ``--reference-samples``,
   seed 0, adaptive sampling off), the passes (``--pass-samples``), and the image the fit is
   made on: random walk at ``--fit-samples`` with another seed (1);
2. the fit (``core.fit.fit_scene``) of every technique of ``--methods`` on that noisy image;
3. each technique at its default quality, unfitted and fitted, scored against the converged
   reference: relative RMSE over the subsurface pixels after 2 x 2 box downsampling (the
   measure ``compare`` uses, docs/references.md §8), and the share of the no-SSS error removed;
4. frame B: camera and lights turned by ``--turn`` degrees about the vertical axis through the
   subsurface objects' centre; new passes and reference; the fit of frame A applied unchanged.

The cost of the fit: the random-walk render it needs plus the fit itself, against the converged
reference render it stands in for (the passes are needed by every technique anyway; their time is
listed apart). Also per material: which technique is best and how fast each one is, for
``apply --method auto``. Writes ``benchmarks/results/fit.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import platform
import tempfile
import time

SAMPLE_SCENES = ("head_frontlit", "backlit_thin", "wax_marble", "depth_leak")
#: Scenes whose light comes mainly from behind (the issue's "back-lit" class); the rest are diffusion scenes.
BACKLIT = ("backlit_thin",)


def _turn(bpy, scene, degrees: float) -> None:
    """Turn the camera and the lights about the vertical axis through the subsurface objects' centre."""
    from mathutils import Matrix, Vector

    from sss_lab.blender.describe import principled_node

    centres = []
    for obj in scene.objects:
        if obj.type != "MESH" or obj.hide_render:
            continue
        for slot in obj.material_slots:
            node = principled_node(slot.material)
            if node is not None and node.inputs["Subsurface Weight"].default_value > 0:
                centres.append(obj.matrix_world @ (sum((Vector(c) for c in obj.bound_box), Vector()) / 8.0))
                break
    centre = sum(centres, Vector()) / max(len(centres), 1)
    rot = Matrix.Translation(centre) @ Matrix.Rotation(math.radians(degrees), 4, "Z") @ Matrix.Translation(-centre)
    for obj in scene.objects:
        if obj.type in ("CAMERA", "LIGHT"):
            obj.matrix_world = rot @ obj.matrix_world
    bpy.context.view_layer.update()


def _frame(bpy, scene, work: str, label: str, args, log) -> dict:
    from sss_lab.blender.reference_cache import cached_reference, scene_fingerprint
    from sss_lab.blender.render_passes import render_passes
    from sss_lab.core import exr, sequence

    fingerprint = scene_fingerprint(scene)
    cache = os.path.join(args.cache, label)
    ref, ref_s, _ = cached_reference(
        scene,
        cache,
        samples=args.reference_samples,
        seed=0,
        resolution=None,
        method=None,
        log=log,
        fingerprint=fingerprint,
    )
    noisy, noisy_s, _ = cached_reference(
        scene, cache, samples=args.fit_samples, seed=1, resolution=None, method=None, log=log, fingerprint=fingerprint
    )
    start = time.perf_counter()
    written = render_passes(
        scene, os.path.join(work, label), samples=args.pass_samples, seed=0, overwrite=True, log=None
    )
    passes_s = time.perf_counter() - start
    path = next(p for p in written if p.endswith(".exr"))
    return {
        "passes": exr.read_passes(path),
        "scene": sequence.load_scene(path),
        "reference": ref,
        "noisy": noisy,
        "seconds": {"reference": ref_s, "fit_render": noisy_s, "passes": passes_s},
    }


def _mask(passes, desc):
    import numpy as np

    index = np.rint(np.nan_to_num(passes["Material Index"])).astype(np.int64)
    return np.isin(index, [m.index for m in desc.materials if m.scatters])


def _score(frame: dict, desc, techniques) -> dict:
    """rel. RMSE of no SSS and each technique (with ``desc``'s fits) against the converged reference,
    and each technique's apply time."""
    from sss_lab.core import apply as core_apply
    from sss_lab.core import metrics

    passes, ref = frame["passes"], frame["reference"]
    mask = _mask(passes, desc)
    out = {"no SSS": {"rel_rmse": metrics.compare_images(passes["Combined"], ref, mask, box=2)["rel_rmse"]}}
    for t in techniques:
        start = time.perf_counter()
        layers = core_apply.apply(passes, desc, t)
        seconds = time.perf_counter() - start
        image = layers[core_apply.layer_names(t)[0]]
        out[t] = {"rel_rmse": metrics.compare_images(image, ref, mask, box=2)["rel_rmse"], "apply_s": seconds}
    return out


def _unfitted(desc):
    return dataclasses.replace(desc, materials=tuple(dataclasses.replace(m, fit={}) for m in desc.materials))


def _removed(no_sss: float, err: float) -> float:
    return (no_sss - err) / no_sss if no_sss else float("nan")


def run_scene(bpy, blend: str, work: str, args, log) -> dict:
    from sss_lab.core.fit import fit_scene, with_fits

    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(blend), load_ui=False)
    scene = bpy.context.scene
    name = os.path.splitext(os.path.basename(blend))[0]
    methods = tuple(args.methods.split(","))
    a = _frame(bpy, scene, work, f"{name}_A", args, log)
    desc = _unfitted(a["scene"])
    start = time.perf_counter()
    results, problems = fit_scene(a["passes"], desc, a["noisy"], techniques=methods, samples=args.fit_samples, log=log)
    fit_s = time.perf_counter() - start
    fitted = with_fits(desc, results)
    row = {
        "scene": name,
        "class": "back-lit" if name in BACKLIT else "diffusion",
        "fits": [r.to_dict() for r in results],
        "problems": problems,
        "seconds": {**a["seconds"], "fit": fit_s},
    }
    row["A"] = {"unfitted": _score(a, desc, methods), "fitted": _score(a, fitted, methods)}
    # The fit against its own noisy image: does it hold against the converged reference?
    row["A"]["fitted_vs_noisy"] = _score({**a, "reference": a["noisy"]}, fitted, methods)
    _turn(bpy, scene, args.turn)
    b = _frame(bpy, scene, work, f"{name}_B", args, log)
    carried = dataclasses.replace(
        _unfitted(b["scene"]),
        materials=tuple(
            dataclasses.replace(m, fit=next((f.fit for f in fitted.materials if f.name == m.name), {}))
            for m in b["scene"].materials
        ),
    )
    row["B"] = {"unfitted": _score(b, _unfitted(b["scene"]), methods), "fitted": _score(b, carried, methods)}
    row["seconds_B"] = b["seconds"]
    for frame in ("A", "B"):
        for kind in ("unfitted", "fitted"):
            s = row[frame][kind]
            best = min(methods, key=lambda t: s[t]["rel_rmse"])
            s["best"] = best
            s["removed"] = _removed(s["no SSS"]["rel_rmse"], s[best]["rel_rmse"])
    cost = row["seconds"]
    row["fit_cost_share"] = (cost["fit_render"] + cost["fit"]) / cost["reference"]
    return row


def _median(values):
    v = sorted(x for x in values if x == x)
    if not v:
        return float("nan")
    n = len(v)
    return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.fit", description=__doc__.split("\n\n")[0])
    parser.add_argument("blends", nargs="*", help="scenes (default: the four sample scenes)")
    parser.add_argument("--reference-samples", type=int, default=512)
    parser.add_argument("--fit-samples", type=int, default=32)
    parser.add_argument("--pass-samples", type=int, default=64)
    parser.add_argument("--methods", default="ssss,burley,combined")
    parser.add_argument("--turn", type=float, default=20.0, help="degrees camera and lights turn for frame B")
    parser.add_argument("--cache", default=os.path.join(tempfile.gettempdir(), "sss_lab_fit_bench"))
    parser.add_argument("--out", default=os.path.join("benchmarks", "results", "fit.json"))
    args = parser.parse_args(argv)
    import bpy

    from benchmarks._common import write_results

    def log(line):
        print(line, flush=True)

    with tempfile.TemporaryDirectory(prefix="sss_lab_fit_bench_") as work:
        blends = args.blends
        if not blends:
            import subprocess
            import sys

            root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
            subprocess.run(
                [sys.executable, os.path.join(root, "sample_blends", "build_scenes.py"), *SAMPLE_SCENES, "--out", work],
                check=True,
                stdout=subprocess.DEVNULL,
            )
            blends = [os.path.join(work, f"{n}.blend") for n in SAMPLE_SCENES]
        rows = [run_scene(bpy, b, work, args, log) for b in blends]
    summary = {}
    for cls in ("diffusion", "back-lit"):
        sel = [r for r in rows if r["class"] == cls]
        if sel:
            summary[cls] = {
                f"{frame} {kind}": _median([r[frame][kind]["removed"] for r in sel])
                for frame in ("A", "B")
                for kind in ("unfitted", "fitted")
            }
    summary["fit cost share (median)"] = _median([r["fit_cost_share"] for r in rows])
    data = {
        "definition": "rel. RMSE over the subsurface pixels after 2x2 box downsampling against Cycles random walk"
        " at reference_samples; removed = share of the no-SSS error the best technique removes",
        "settings": {k: v for k, v in vars(args).items() if k != "blends"},
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "note": "shared, loaded 2-core machine"},
        "blender": bpy.app.version_string,
        "scenes": rows,
        "summary": summary,
    }
    write_results(args.out, data)
    for r in rows:
        for frame in ("A", "B"):
            for kind in ("unfitted", "fitted"):
                s = r[frame][kind]
                errs = ", ".join(f"{t} {s[t]['rel_rmse']:.3f}" for t in args.methods.split(","))
                print(
                    f"{r['scene']:14s} {frame} {kind:8s} no SSS {s['no SSS']['rel_rmse']:.3f}, {errs}; best {s['best']}"
                    f" removes {100 * s['removed']:.0f} %"
                )
        print(f"{r['scene']:14s} fit cost {100 * r['fit_cost_share']:.1f} % of the reference render")
    print(summary)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
