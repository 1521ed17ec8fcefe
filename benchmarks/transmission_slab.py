"""The canonical check of the light from behind: a wide slab of known thickness lit from behind,
rendered small with Cycles, against the combined technique's transmitted light (docs/references.md §14).

Per material of the fidelity suite's palette, slab thickness x and view angle (0 and 60 degrees
to the normal): a 40 x 40 cm slab, x thick, under a sun of strength 1 shining straight through it
from behind, a black world, an orthographic camera looking at the middle 2 cm of the front face
(16 x 16 px). Cycles (the material's own
subsurface method) gives the front's radiance; the model gives W x (1 / pi) x T_c(x), with T_c
the random walk's slab transmittance (``core/optics/transmittance.py``; Christensen-Burley: Burley's
law) and W the exit weight read from the Diffuse Color pass (``core.optics.medium.exit_weight``). The
previous model, Burley's law with the diffusion's d and no exit weight, is listed beside it.

    nice -n 10 .venv/bin/python -m benchmarks.transmission_slab [--samples 256]

writes ``benchmarks/results/transmission_slab.json`` and prints the table.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results", "transmission_slab.json")
THICKNESSES_MM = (1.0, 2.0, 4.0, 8.0, 16.0)
#: Camera angles to the slab's normal (the walk's entry refracts the view).
VIEWS_DEG = (0.0, 60.0)
SIZE = 16


def _materials():
    from . import scene_kit as kit

    return {
        "jade (Random Walk)": lambda: kit.jade(),
        "wax (Random Walk)": lambda: kit.wax(),
        "skin (Random Walk Skin)": lambda: kit.skin(method="RANDOM_WALK_SKIN", scale=0.012),
        "milk (Random Walk Legacy)": lambda: kit.milk(method="RANDOM_WALK_LEGACY", scale=0.06),
        "marble (Christensen-Burley)": lambda: kit.new_material(
            "Marble", (0.83, 0.791, 0.753), radius=(1.0, 0.655, 0.464), scale=0.1, method="BURLEY", ior=1.5
        ),
    }


def _scene(material, thickness, view_deg: float = 0.0):
    from . import scene_kit as kit

    scene = kit.reset_scene(world_color=(0.0, 0.0, 0.0))
    kit.add_object(scene, "Slab", kit.box_mesh("Slab", (0.4, thickness, 0.4)), material=material(), smooth=False)
    a = math.radians(view_deg)
    cam = kit.add_camera(scene, (0.0, -0.3 * math.cos(a), 0.3 * math.sin(a)), (0.0, 0.0, 0.0))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 0.02
    kit.add_light(scene, "Back", "SUN", (0.0, 1.0, 0.0), (0.0, 0.0, 0.0), 1.0, angle=0.0)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    return scene


def _measure_one(name, material, mm: float, view: float, samples: int) -> dict:
    from sss_lab.blender.describe import describe_scene
    from sss_lab.blender.reference_cache import cached_reference
    from sss_lab.blender.render_passes import render_passes
    from sss_lab.core.optics.medium import burley_transmittance_rgb, exit_weight, medium_of, slab_transmittance_rgb
    from sss_lab.core.pipeline.mapping import burley_d, mean_free_path
    from sss_lab.core.scene import exr

    from .fidelity import scenes as suite

    x = mm / 1000.0
    scene = _scene(material, x, view)
    suite.prepare(scene)
    with tempfile.TemporaryDirectory(prefix="sss_lab_slab_") as tmp:
        image, seconds, _ = cached_reference(
            scene, tmp, samples=samples, seed=0, resolution=(SIZE, SIZE), method=None, log=lambda _l: None
        )
        written = render_passes(scene, os.path.join(tmp, "p"), techniques=("burley",), samples=4, frames=[1], log=None)
        passes = exr.read_passes(next(p for p in written if p.endswith(".exr")))
    mat = next(m for m in describe_scene(scene).materials if m.scatters)
    cycles = image[..., :3].reshape(-1, 3).mean(axis=0)
    albedo = passes["Diffuse Color"][..., :3].reshape(-1, 3).mean(axis=0)
    medium = medium_of(mat)
    w = exit_weight(albedo.reshape(1, 1, 3), medium)[0, 0]
    view_cos = np.array([math.cos(math.radians(view))])
    t_new = slab_transmittance_rgb(np.array([x]), tuple(mean_free_path(mat)), medium, view_cos=view_cos)[0]
    new = w * t_new / math.pi
    old = burley_transmittance_rgb(np.array([x]), burley_d(mat))[0] / math.pi
    return {
        "material": name,
        "thickness_mm": mm,
        "view_deg": view,
        "cycles": [round(float(v), 5) for v in cycles],
        "model": [round(float(v), 5) for v in new],
        "burley_law": [round(float(v), 5) for v in old],
        "exit_weight": [round(float(v), 4) for v in w],
        "render_s": round(seconds, 2),
    }


def measure(samples: int, log=print) -> list[dict]:
    rows = []
    for name, material in _materials().items():
        for view in VIEWS_DEG:
            for mm in THICKNESSES_MM:
                rows.append(_measure_one(name, material, mm, view, samples))
                r = rows[-1]
                log(f"{name} {mm:4.0f} mm, view {view:2.0f} deg: Cycles {r['cycles']}  model {r['model']}")
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=256, help="Cycles samples per slab (default 256)")
    parser.add_argument("--out", default=RESULTS)
    args = parser.parse_args(argv)
    import bpy

    start = time.perf_counter()
    rows = measure(args.samples)
    from benchmarks._common import write_results

    write_results(
        args.out,
        {
            "command": "python -m benchmarks.transmission_slab" + (" " + " ".join(argv or sys.argv[1:])).rstrip(),
            "blender": bpy.app.version_string,
            "samples": args.samples,
            "generated_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "seconds": round(time.perf_counter() - start, 1),
            "rows": rows,
        },
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
