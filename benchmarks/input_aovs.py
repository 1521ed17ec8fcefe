"""What reading linked subsurface inputs per pixel costs: ``make bench`` runs it after the speed
cases (``python -m benchmarks.input_aovs``).

One scene rendered through ``render_passes`` for Burley at 1920 x 1080 (``--resolution``): a skin ball (the
fidelity suite's head light set-up on a sphere) whose Base Color, Subsurface Scale and Weight are
linked (a noise texture through a colour ramp, a Map Range, a Math node: every input AOV but the
Radius), and the same ball with the values typed in. Per case: the render's wall time (Cycles at
``--samples``, fastest of ``--repeat``), the passes file's size, the bytes of the passes held in
memory (every array ``read_passes`` returns), and ``plan`` + ``apply`` on them (the medians and
the weight mix included; fastest of ``--repeat``). The typed-in case renders exactly the passes
Burley reads, so its figures are the baseline: the ratios are the cost of the linked inputs.
Writes ``benchmarks/results/input_aovs.json``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

from benchmarks import _common
from benchmarks import scene_kit as kit

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "input_aovs.json")


def _ball(linked: bool, res: tuple[int, int]):
    scene = kit.reset_scene()
    mat = kit.skin(scale=0.012)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    if linked:
        tree = mat.node_tree
        noise = tree.nodes.new("ShaderNodeTexNoise")
        ramp = tree.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].color = (0.36, 0.18, 0.1, 1.0)
        ramp.color_ramp.elements[1].color = (0.5, 0.27, 0.16, 1.0)
        tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
        tree.links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
        span = tree.nodes.new("ShaderNodeMapRange")
        span.inputs["To Min"].default_value, span.inputs["To Max"].default_value = 0.006, 0.018
        tree.links.new(noise.outputs["Fac"], span.inputs["Value"])
        tree.links.new(span.outputs["Result"], bsdf.inputs["Subsurface Scale"])
        weight = tree.nodes.new("ShaderNodeMath")
        weight.inputs[0].default_value, weight.inputs[1].default_value = 0.5, 0.4
        tree.links.new(weight.outputs[0], bsdf.inputs["Subsurface Weight"])
    kit.add_object(scene, "Ball", kit.uv_sphere_mesh("Ball", 0.1, segments=64, rings=32), material=mat)
    kit.wall(scene, 0.3, z=0.0)
    kit.add_camera(scene, (0.0, -0.6, 0.05), (0.0, 0.0, 0.0), lens=50.0)
    kit.add_light(scene, "Key", "AREA", (-0.5, -0.35, 0.25), (0.0, 0.0, 0.0), 20.0, size=0.02)
    scene.render.resolution_x, scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    return scene


def _case(linked: bool, res: tuple[int, int], samples: int, repeat: int) -> dict:
    from sss_lab.blender.render_passes import render_passes
    from sss_lab.core.pipeline import apply as core_apply
    from sss_lab.core.pipeline.sequence import load_scene
    from sss_lab.core.scene.exr import read_passes

    render_s = []
    with tempfile.TemporaryDirectory(prefix="sss_lab_input_aovs_") as tmp:
        exr = None
        for i in range(repeat):
            scene = _ball(linked, res)
            start = time.perf_counter()
            exr, _ = render_passes(scene, os.path.join(tmp, str(i)), techniques=["burley"], samples=samples, log=None)
            render_s.append(time.perf_counter() - start)
        assert exr is not None
        passes = read_passes(exr)
        desc = load_scene(exr)
        size = os.path.getsize(exr)
        held = sum(passes[n].nbytes for n in passes.names)
        core_apply.apply(passes, desc, "burley")  # loads the kernels
        apply_s = _common.fastest(lambda: core_apply.apply(passes, desc, "burley"), repeat)
    return {
        "per_pixel_inputs": sorted({k for m in desc.materials for k in m.per_pixel}),
        "passes": list(passes.names),
        "render_s": round(min(render_s), 3),
        "exr_bytes": size,
        "passes_bytes_in_memory": held,
        "plan_and_apply_s": round(apply_s, 4),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--samples", type=int, default=4, help="Cycles samples of the passes (default 4)")
    _common.add_options(parser, repeat=2, results=RESULTS)
    args = parser.parse_args(argv)
    res = _common.resolution(parser, args.resolution)
    load = os.getloadavg()
    typed = _case(False, res, args.samples, args.repeat)
    linked = _case(True, res, args.samples, args.repeat)
    data = {
        "command": " ".join(["python -m benchmarks.input_aovs", *sys.argv[1:]]),
        "resolution": list(res),
        "samples": args.samples,
        "load_before": [round(v, 2) for v in load],
        "load_after": [round(v, 2) for v in os.getloadavg()],
        "typed_in": typed,
        "linked": linked,
        "ratios": {
            k: round(linked[k] / typed[k], 3)
            for k in ("render_s", "exr_bytes", "passes_bytes_in_memory", "plan_and_apply_s")
        },
    }
    _common.write_results(args.out, data)
    for case in ("typed_in", "linked"):
        c = data[case]
        print(
            f"{case}: render {c['render_s']:.2f} s, EXR {c['exr_bytes'] / 1e6:.1f} MB, passes in memory"
            f" {c['passes_bytes_in_memory'] / 1e6:.1f} MB, plan + apply {c['plan_and_apply_s']:.3f} s"
        )
    print("linked / typed in:", data["ratios"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
