"""How much of the back-lit error is the thickness map's (docs/references.md §14).

For the back-lit scenes of the fidelity suite and of ``benchmarks/fidelity/backlit_extra.py``:

1. per baked mesh, the map's thickness D sqrt(1 - t) at each vertex against the distance to the
   far side along the inward normal (ray cast on the mesh as rendered): the median ratio;
2. the same scenes scored (``benchmarks.fidelity.run``) with an oracle map: modifiers applied,
   then at each vertex the slab-law value 1 - (min(x, D) / D)^2 of that ray-cast distance x, in
   place of the baked ambient occlusion. The scene Cycles renders is the same (the modifiers'
   result), so the stored references still hold.

    nice -n 10 .venv/bin/python -m benchmarks.thickness_oracle

writes ``benchmarks/results/thickness_oracle.json``.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from .fidelity import run
from .fidelity import scenes as suite

RESULTS = "benchmarks/results/thickness_oracle.json"
EXTRA = ("benchmarks.fidelity.backlit_extra", "benchmarks/fidelity/backlit_extra_references")


def _ray_thickness(obj, depsgraph, distance: float) -> tuple[np.ndarray, np.ndarray]:
    """(distance to the far side along -N per vertex of the mesh as rendered, the map's D sqrt(1 - t)
    there); object space, the suite's objects are not scaled."""
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.data
    att = mesh.attributes[suite.THICKNESS_AOV]
    vals = np.empty(len(att.data) * 4, np.float32)
    att.data.foreach_get("color", vals)
    true, mapped = [], []
    for v, t in zip(mesh.vertices, vals[0::4], strict=True):
        hit, loc, _n, _i = ev.ray_cast(v.co - v.normal * 1e-5, -v.normal)
        if hit:
            true.append((loc - v.co).length)
            mapped.append(distance * float(np.sqrt(max(0.0, 1.0 - float(t)))))
    return np.array(true), np.array(mapped)


def map_ratios(log=print) -> list[dict]:
    import importlib

    import bpy

    rows = []
    for module, _store in ((None, None), EXTRA):
        table = suite.SCENES if module is None else importlib.import_module(module).SCENES
        for name, entry in table.items():
            if entry.kind != "backlit":
                continue
            scene = suite.build(name, table)
            suite.prepare(scene)
            baked = {r.object: r for r in suite.bake(scene)}
            depsgraph = bpy.context.evaluated_depsgraph_get()
            for obj in suite.subsurface_objects(scene):
                d = baked[obj.name].distance_su
                true, mapped = _ray_thickness(obj, depsgraph, d)
                ok = true > 0
                rows.append(
                    {
                        "scene": name,
                        "object": obj.name,
                        "distance_su": round(d, 5),
                        "median_ray_thickness_su": round(float(np.median(true)), 5),
                        "median_map_thickness_su": round(float(np.median(mapped)), 5),
                        "median_ratio": round(float(np.median(mapped[ok] / true[ok])), 3),
                    }
                )
                log(f"{name} {obj.name}: map / ray thickness {rows[-1]['median_ratio']}")
    return rows


def _oracle_bake(scene):
    """Apply the modifiers, bake as the suite does, then replace the map by the slab law of the
    ray-cast thickness."""
    import bpy

    depsgraph = bpy.context.evaluated_depsgraph_get()
    for obj in suite.subsurface_objects(scene):
        if obj.modifiers:
            obj.data = bpy.data.meshes.new_from_object(obj.evaluated_get(depsgraph))
            obj.modifiers.clear()
    results = _BAKE(scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    distances = {r.object: r.distance_su for r in results}
    for obj in suite.subsurface_objects(scene):
        d = distances[obj.name]
        att = obj.data.attributes[suite.THICKNESS_AOV]
        vals = np.empty(len(att.data) * 4, np.float32)
        att.data.foreach_get("color", vals)
        ev = obj.evaluated_get(depsgraph)
        for i, v in enumerate(obj.data.vertices):
            hit, loc, _n, _i = ev.ray_cast(v.co - v.normal * 1e-5, -v.normal)
            x = (loc - v.co).length if hit else d
            vals[4 * i : 4 * i + 3] = 1.0 - min(x / d, 1.0) ** 2
        att.data.foreach_set("color", vals)
        obj.data.update()
    return results


_BAKE = suite.bake


def oracle_scores(log=print) -> list[dict]:
    rows = []
    suite.bake = _oracle_bake
    try:
        for module, store in ((None, run.references.STORE), EXTRA):
            scenes = run.load_scenes_module(module)
            names = [n for n, s in scenes.SCENES.items() if s.kind == "backlit"]
            out = run.run(
                names, scenes=scenes, store=store, qualities={"combined": ({},), "sta": ({},)}, log=lambda _l: None
            )
            for s in out["scenes"]:
                for r in s["rows"]:
                    if r["technique"] == "none":
                        continue
                    rows.append(
                        {
                            "scene": s["scene"],
                            "technique": r["technique"],
                            "rel_rmse": round(r["rel_rmse"], 4),
                            "removed": round(r["removed"], 4),
                            "energy": r["energy"],
                        }
                    )
                    log(f"{s['scene']} {r['technique']}: oracle map removes {r['removed']:+.0%}")
    finally:
        suite.bake = _BAKE
    return rows


def main(argv=None) -> int:
    import bpy

    from benchmarks._common import write_results

    start = time.perf_counter()
    ratios = map_ratios()
    scores = oracle_scores()
    write_results(
        RESULTS,
        {
            "command": "python -m benchmarks.thickness_oracle",
            "blender": bpy.app.version_string,
            "generated_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "seconds": round(time.perf_counter() - start, 1),
            "map_over_ray_thickness": ratios,
            "oracle_map_scores": scores,
        },
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
