"""Compositor node groups against the NumPy passes at 1920 x 1080:
``.venv/bin/python -m benchmarks.compositor`` (from the repository root).

Inputs: the synthetic plane-and-spheres passes of ``core/study/synthetic.py`` (two scattering
materials, Skin and Wax, two sun lights), written to a multilayer EXR in a temporary folder,
with the profiles of ``benchmarks/speed.py``: Skin d = (4, 1.6, 0.8) mm (its red kernel spans
about 30 pixels at the spheres' depth, a face in a close-up), Wax 1.5 times that (both as
Christensen-Burley materials, d = radius / (4 pi)). Per technique:

- NumPy: ``core.pipeline.apply.apply`` on the passes (every scattering material, composited), with the
  default parameters (SSSS 17 taps pre-integrated, Burley 32 samples, STA's defaults);
- compositor: the chain ``nodes.setup.build_chain`` builds (one group per material or light,
  read from an Image node: no Render Layers node, so Blender only composites), timed as
  ``bpy.ops.render.render()`` on the CPU compositor; a tree that only passes the image through
  is timed as well (loading and output, included in every compositor figure);
- group build: ``ensure_*`` (kernel images from ``core``), a one-time cost;
- Burley twice: its Convolve route (the exact profile) and its Blur-node route (six Gaussians,
  ``route="gaussians"``), the second also against the first;
- ``--devices CPU,GPU`` times every chain on each compositor device (GPU needs a GPU context;
  without a GPU it runs on whatever OpenGL the machine has, which the results name);
- difference: relative RMS of the SSS term (result minus Combined) over the scattering
  materials' pixels, compositor vs NumPy with the groups' energy (``energy="lambert"``; also
  against NumPy's defaults, whose energy model the groups do not have). The spheres vary in depth, so this is the
  depth-varying case: the groups use one screen scale per material (its median depth) and
  ignore depth. The same against NumPy on passes whose depth is flattened to each material's
  median (Burley with 1024 samples, so that the spiral's own error is left out) says how much
  of the difference is depth.

Each timing is the fastest of ``--repeat`` runs after a warm-up (the machine is shared and
noisy). Writes ``benchmarks/results/compositor.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import platform
import tempfile
import time

import numpy as np

from benchmarks._common import add_options, fastest, resolution, write_results
from benchmarks.speed import D_SU

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "compositor.json")
#: (name in the results, technique, build options).
VARIANTS = (
    ("sta", "sta", {}),
    ("ssss", "ssss", {}),
    ("burley", "burley", {"route": "convolve"}),
    ("burley_gaussians", "burley", {"route": "gaussians"}),
)


def _rel_rms(a, b) -> float:
    return round(float(np.sqrt(np.mean((a - b) ** 2) / max(np.mean(b * b), 1e-30))), 4)


def _gpu_device() -> dict:
    """What the GPU compositor ran on (Blender's ``gpu.platform``, initialized by the GPU composites)."""
    import gpu

    out = {}
    for key in ("renderer", "vendor", "version", "device_type"):
        try:
            out[key] = str(getattr(gpu.platform, f"{key}_get")())
        except Exception as exc:  # not initialized: the GPU composites did not run on a GPU context
            out[key] = f"unknown ({exc})"
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.compositor", description=__doc__.split("\n\n")[0])
    add_options(parser, repeat=3, results=RESULTS)
    parser.add_argument("--devices", default="CPU", help="compositor devices to time, comma-separated (CPU, GPU)")
    parser.add_argument("--only", default="", help="variants to run, comma-separated (default: all)")
    args = parser.parse_args(argv)
    devices = [d.strip().upper() for d in args.devices.split(",") if d.strip()]
    if not devices or any(d not in ("CPU", "GPU") for d in devices):
        parser.error(f"--devices: expected CPU and/or GPU, got {args.devices!r}")
    variants = [v for v in VARIANTS if not args.only or v[0] in args.only.split(",")]
    width, height = resolution(parser, args.resolution)

    import bpy

    from sss_lab.blender import compat
    from sss_lab.core.compute.backend import active as backend_name
    from sss_lab.core.pipeline import mapping
    from sss_lab.core.pipeline.apply import apply
    from sss_lab.core.scene.exr import Passes, read_layers, read_passes
    from sss_lab.core.study.synthetic import sphere_scene, write_scene
    from sss_lab.nodes import setup
    from sss_lab.nodes.burley import ensure_burley_group
    from sss_lab.nodes.ssss import ensure_ssss_group
    from sss_lab.nodes.sta import ensure_sta_group

    folder = tempfile.mkdtemp(prefix="sss_lab_bench_compositor_")
    passes, desc = sphere_scene(width, height)
    widths = {"Skin": 1.0, "Wax": 1.5}
    desc = dataclasses.replace(
        desc,
        materials=tuple(
            dataclasses.replace(
                m,
                method="BURLEY",
                subsurface_radius=tuple(4 * math.pi * d * widths.get(m.name, 1.0) for d in D_SU),
                subsurface_scale=1.0,
            )
            for m in desc.materials
        ),
    )
    path = write_scene(os.path.join(folder, "passes.exr"), passes, desc)
    loaded = read_passes(path)
    index = passes["Material Index"]
    scattering = [m for m in desc.materials if m.scatters]
    on = np.isin(index, [m.index for m in scattering])
    scale = {}
    for m in scattering:
        depth = float(np.median(passes["Depth"][index == m.index]))
        scale[m.index] = float(desc.camera.pixels_per_unit(np.array([[depth]], np.float32))[0, 0])
    combined = passes["Combined"][..., :3]
    flat_depth = passes["Depth"].copy()
    for m in scattering:
        flat_depth[index == m.index] = np.median(flat_depth[index == m.index])
    flat_passes = Passes({**passes, "Depth": flat_depth})

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    render = scene.render
    render.resolution_x, render.resolution_y, render.resolution_percentage = width, height, 100
    render.use_compositing = True
    compat.set_compositor_device(scene, "CPU")
    compat.set_single_image(render.image_settings, "OPEN_EXR", color_depth="32")
    scene.view_settings.view_transform = "Standard"
    image = bpy.data.images.load(path)

    def tree_with(technique, options=None):
        old = compat.compositor_tree(scene)
        if old is not None:
            scene.compositing_node_group = None
            bpy.data.node_groups.remove(old)
        tree = compat.compositor_tree(scene, create=True)
        result = compat.compositor_result_socket(tree)
        src = tree.nodes.new("CompositorNodeImage")
        src.image = image
        out = src.outputs["Combined"]
        if technique is not None:
            out, _ = setup.build_chain(
                tree, src, image=out, technique=technique, scene=desc, options=options or {}, pixels_per_unit=scale
            )
        tree.links.new(out, result)
        return tree

    def composite():
        bpy.ops.render.render()

    def composite_to_file(name):
        render.filepath = os.path.join(folder, name)
        bpy.ops.render.render(write_still=True)
        (layer,) = read_layers(render.filepath).layers.values()
        return np.array(layer[..., :3])

    tree_with(None)
    baseline = {}
    for device in devices:
        compat.set_compositor_device(scene, device)
        baseline[device] = fastest(composite, args.repeat, warm_up=True)
        print(f"compositor overhead on {device} (a tree passing the image through): {baseline[device] * 1e3:8.0f} ms")
    results = {}
    outputs = {}
    for key, technique, options in variants:
        entry = {}
        kernels = {}
        t0 = time.perf_counter()
        if technique == "sta":
            ensure_sta_group()
        for m in scattering if technique != "sta" else ():
            name = setup.group_name(technique, m.name)
            d = mapping.burley_d(m)
            if technique == "ssss":
                group = ensure_ssss_group(name=name, pixels_per_unit=scale[m.index], d_su=d)
            else:
                group = ensure_burley_group(name=name, pixels_per_unit=scale[m.index], d_su=d, **options)
            kernels[m.name] = 2 * group["sss_lab"]["kernel_radius_px"] + 1
        entry["group_build_ms"] = round((time.perf_counter() - t0) * 1e3, 1)
        entry["kernel_size_px"] = kernels
        tree = tree_with(technique, options)
        inner = [
            node.bl_idname
            for n in tree.nodes
            if getattr(n, "node_tree", None) is not None
            for node in n.node_tree.nodes
        ]
        entry["convolve_nodes"] = inner.count("CompositorNodeConvolve")
        entry["blur_nodes"] = inner.count("CompositorNodeBlur")
        for device in devices:
            compat.set_compositor_device(scene, device)
            seconds = fastest(composite, args.repeat, warm_up=True)
            entry["compositor_ms" if device == "CPU" else f"compositor_{device.lower()}_ms"] = round(seconds * 1e3, 1)
        compat.set_compositor_device(scene, devices[0])
        numpy_s = fastest(lambda t=technique: apply(loaded, desc, t), args.repeat, warm_up=True)
        entry["numpy_ms"] = round(numpy_s * 1e3, 1)
        got = composite_to_file(f"{key}.exr")
        outputs[key] = got
        # The groups keep the passes' energy: the NumPy technique they are compared with does too
        # (energy="lambert"); its default ("object") also models Cycles' energy, which no group has.
        same = {"energy": "lambert"} if technique != "sta" else {}
        want = apply(loaded, desc, technique, **same)[f"SSSLab.{technique}.Image"][..., :3]
        a, b = (got - combined)[on], (want - combined)[on]
        entry["rel_rms_sss_vs_numpy"] = _rel_rms(a, b)
        default = apply(loaded, desc, technique)[f"SSSLab.{technique}.Image"][..., :3]
        entry["rel_rms_sss_vs_numpy_default"] = _rel_rms(a, (default - combined)[on])
        extra = {"n_samples": 1024, **same} if technique == "burley" else same
        flat = apply(flat_passes, desc, technique, **extra)[f"SSSLab.{technique}.Image"][..., :3]
        entry["rel_rms_sss_vs_numpy_median_depth"] = _rel_rms(a, (flat - combined)[on])
        if key == "burley_gaussians" and "burley" in outputs:
            entry["rel_rms_sss_vs_convolve_route"] = _rel_rms(a, (outputs["burley"] - combined)[on])
        results[key] = entry
        timing = "   ".join(
            f"compositor {d} {entry['compositor_ms' if d == 'CPU' else f'compositor_{d.lower()}_ms']:8.0f} ms"
            for d in devices
        )
        print(
            f"{key:17s} {timing}   numpy {numpy_s * 1e3:8.0f} ms   "
            f"group build {entry['group_build_ms']:6.0f} ms   kernels {kernels}   "
            f"SSS rel. RMS vs numpy {entry['rel_rms_sss_vs_numpy']:.3f} "
            f"(median depth: {entry['rel_rms_sss_vs_numpy_median_depth']:.4f})"
            + (
                f"   vs the Convolve route {entry['rel_rms_sss_vs_convolve_route']:.4f}"
                if "rel_rms_sss_vs_convolve_route" in entry
                else ""
            )
        )
    data = {
        "resolution": [width, height],
        "repeat": args.repeat,
        "statistic": "fastest of the repeats after a warm-up",
        "scene": "core.study.synthetic.sphere_scene (Skin and Wax scatter, two sun lights)",
        "d_su": {name: [round(d * f, 6) for d in D_SU] for name, f in widths.items()},
        "compositor_devices": devices,
        "gpu_device": _gpu_device() if "GPU" in devices else None,
        "compositor_image_only_ms": {d: round(t * 1e3, 1) for d, t in baseline.items()},
        "numpy_backend": backend_name(),
        "pixels_per_unit": {m.name: round(scale[m.index], 2) for m in scattering},
        "machine": {
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "numpy": np.__version__,
            "blender": bpy.app.version_string,
        },
        "techniques": results,
    }
    write_results(args.out, data)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
