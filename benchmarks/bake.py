"""Thickness-bake speed: ``.venv/bin/python -m benchmarks.bake`` (from the repository root).

Bakes a UV sphere of about 100k vertices (400 x 250 segments, radius 1, automatic distance)
with ``bake_thickness``, Cycles on the CPU:

- to a colour attribute at 32 rays per vertex;
- to a 1024 x 1024 float image at 32 rays per texel (saved as OpenEXR into a temporary folder).

Each bake runs ``--repeat`` times after one small warm-up bake (kernel and scene set-up);
the per-object time that ``bake_thickness`` reports (bake + saving + material linking) and
the wall time of the call are written to ``benchmarks/results/bake.json`` and printed.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time


def _sphere(bpy, bmesh, name: str):
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")
    bmesh.ops.create_uvsphere(bm, u_segments=400, v_segments=250, radius=1.0, calc_uvs=True)
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bake", description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=2, help="runs per case (default: %(default)s)")
    parser.add_argument("--samples", type=int, default=32, help="AO rays per vertex or texel (default: %(default)s)")
    parser.add_argument("--resolution", type=int, default=1024, help="image size (default: %(default)s)")
    parser.add_argument("--out", default=os.path.join("benchmarks", "results", "bake.json"))
    args = parser.parse_args(argv)

    import bpy  # noqa: I001  (bmesh only imports once bpy has)
    import bmesh

    from sss_lab.core.scene.thickness import BakeSettings
    from sss_lab.blender.bake import bake_thickness

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.cycles.device = "CPU"
    obj = _sphere(bpy, bmesh, "Sphere")
    vertices = len(obj.data.vertices)
    folder = tempfile.mkdtemp(prefix="sss_lab_bench_bake_")

    def run(settings, objects):
        t0 = time.perf_counter()
        (result,) = bake_thickness(bpy.context, objects, settings, log=None)
        wall = time.perf_counter() - t0
        if result.status != "baked":
            raise RuntimeError(f"benchmark bake failed: {result}")
        return result, wall

    warm = bpy.data.objects.new("Warm", bpy.data.meshes.new("Warm"))
    tetrahedron = [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)]
    warm.data.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], [], tetrahedron)
    scene.collection.objects.link(warm)
    run(BakeSettings(samples=4), [warm])

    cases = {
        "attribute": BakeSettings(samples=args.samples, link_materials=False),
        "image": BakeSettings(
            target="image",
            samples=args.samples,
            resolution_px=args.resolution,
            image_folder=folder,
            link_materials=False,
        ),
    }
    report = {
        "command": "python -m benchmarks.bake",
        "mesh": f"UV sphere 400 x 250 segments, {vertices} vertices, radius 1",
        "blender": bpy.app.version_string,
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "threads": scene.render.threads,
        "cases": {},
    }
    for name, settings in cases.items():
        runs = []
        for _ in range(args.repeat):
            result, wall = run(settings, [obj])
            runs.append({"object_s": round(result.seconds, 3), "wall_s": round(wall, 3)})
        best = min(r["object_s"] for r in runs)
        entry = {
            "samples": settings.samples,
            "distance_su": round(result.distance_su, 6),
            "runs": runs,
            "best_object_s": best,
        }
        if name == "image":
            entry["resolution_px"] = settings.resolution_px
            entry["texels_per_s"] = round(settings.resolution_px**2 / best)
        else:
            entry["vertices"] = vertices
            entry["vertices_per_s"] = round(vertices / best)
        report["cases"][name] = entry
        size = f"{settings.resolution_px}^2 image" if name == "image" else f"{vertices}-vertex attribute"
        print(f"bake {size}, {settings.samples} rays: best {best:.2f} s per object ({len(runs)} runs: {runs})")
    from benchmarks._common import write_results

    write_results(args.out, report)  # atomically, and says so in the one Saved: form
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
