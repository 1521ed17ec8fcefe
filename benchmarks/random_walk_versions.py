"""Cycles' random walk on Blender 5.2 and 4.5 LTS: the same sample scenes, rendered on each.

Run once per version (each writes its images and figures), then make the table from both::

    .venv/bin/python -m benchmarks.random_walk_versions --out out/rw_versions
    .venv-4.5/bin/python -m benchmarks.random_walk_versions --out out/rw_versions
    .venv/bin/python -m benchmarks.random_walk_versions --table out/rw_versions

Per sample scene (as this version's ``sample_blends/build_scenes.py`` builds it) and variant,
Cycles renders the Combined image (CPU, fixed seed, no adaptive sampling or denoising; 32 x 32
and 64 samples by default: a few seconds per image on this project's machine); the table gives
its mean (R, G, B) and its relative RMSE against another image:

- ``rw``: the scene as built: this version's newest random walk with the scene's mean free path
  (5.2: Random Walk; 4.5: its Random Walk, the legacy one, with Subsurface Scale x 4 pi);
- ``rw_seed1``: the same with seed 1 (the noise floor of these settings);
- ``same_inputs``: the legacy random walk with Radius x Scale equal to the mean free path, the
  inputs of 5.2's scene (on 4.5: its Random Walk with 5.2's settings, "the same file");
- ``no_sss``: Subsurface Weight 0.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

VARIANTS = ("rw", "rw_seed1", "same_inputs", "no_sss")
SCENES = ("head_frontlit", "backlit_thin", "wax_marble", "depth_leak")


def _render(scene, path: str, *, samples: int, seed: int, size: int) -> np.ndarray:
    import bpy

    from sss_lab.blender import compat

    scene.render.engine = "CYCLES"
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    cy = scene.cycles
    cy.device = "CPU"
    cy.samples, cy.seed = samples, seed
    cy.use_adaptive_sampling = cy.use_denoising = cy.use_animated_seed = False
    compat.set_single_image(scene.render.image_settings, "OPEN_EXR", color_depth="32")
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True, scene=scene.name)
    image = bpy.data.images.load(path)
    try:
        pixels = np.array(image.pixels[:], dtype=np.float64).reshape(size, size, 4)[::-1, :, :3]
    finally:
        bpy.data.images.remove(image)
    return pixels


def _apply_variant(scene, variant: str) -> list[dict]:
    """Change the scene's subsurface materials for ``variant``; returns what each one is then."""
    from sss_lab.blender import compat
    from sss_lab.blender.describe import material_sss, principled_node, scene_materials
    from sss_lab.core.pipeline import mapping

    described = []
    for mat in scene_materials(scene):
        node = principled_node(mat)
        if node is None or node.inputs["Subsurface Weight"].default_value <= 0:
            continue
        if variant == "no_sss":
            node.inputs["Subsurface Weight"].default_value = 0.0
        elif variant == "same_inputs":
            ell = mapping.mean_free_path(material_sss(mat, 1))
            radius = np.array(node.inputs["Subsurface Radius"].default_value[:3], dtype=np.float64)
            node.subsurface_method = compat.subsurface_method_item("RANDOM_WALK_LEGACY")
            node.inputs["Subsurface Scale"].default_value = float(np.max(ell) / np.max(radius))
        m = material_sss(mat, 1)
        described.append(
            {
                "material": mat.name,
                "method": m.method,
                "radius_x_scale": [round(v, 6) for v in m.radius],
                "mean_free_path": [round(float(v), 6) for v in mapping.mean_free_path(m)],
                "weight": m.subsurface_weight,
            }
        )
    return described


def render_all(out: str, *, samples: int, size: int, scenes) -> None:
    import bpy

    from sss_lab.blender.samples import load_sample_scenes

    builder = load_sample_scenes()
    version = ".".join(map(str, bpy.app.version[:2]))
    folder = os.path.join(out, version)
    os.makedirs(folder, exist_ok=True)
    figures = {"blender": bpy.app.version_string, "samples": samples, "size": size, "scenes": {}}
    for name in scenes:
        blend = builder.build(name, os.path.join(folder, f"{name}.blend"))
        figures["scenes"][name] = {}
        for variant in VARIANTS:
            bpy.ops.wm.open_mainfile(filepath=blend)
            scene = bpy.context.scene
            materials = _apply_variant(scene, variant)
            seed = 1 if variant == "rw_seed1" else 0
            image = _render(scene, os.path.join(folder, f"{name}.{variant}.exr"), samples=samples, seed=seed, size=size)
            np.save(os.path.join(folder, f"{name}.{variant}.npy"), image)
            mean = image.mean(axis=(0, 1)).round(5).tolist()
            figures["scenes"][name][variant] = {"mean": mean, "materials": materials}
            print(f"{version} {name} {variant}: mean {mean}", flush=True)
    with open(os.path.join(folder, "figures.json"), "w", encoding="utf-8") as f:
        json.dump(figures, f, indent=2)
    print(f"Saved: {os.path.join(folder, 'figures.json')}")


def rel_rmse(image: np.ndarray, reference: np.ndarray) -> float:
    return float(np.sqrt(np.mean((image - reference) ** 2) / np.mean(reference**2)))


def table(out: str) -> str:
    """The Markdown table from both versions' images under ``out``."""

    def load(version, name, variant):
        return np.load(os.path.join(out, version, f"{name}.{variant}.npy"))

    def mean(img):
        return float(img.mean())

    lines = [
        "| scene | 5.2 Random Walk: mean | noise floor (seed 1) | 5.2 Legacy, same inputs: mean (rel. RMSE vs 5.2 RW) "
        "| 4.5 Random Walk, same inputs: mean (vs 5.2 Legacy) | 4.5 Random Walk, Scale x 4 pi: mean (vs 5.2 RW) "
        "| 4.5 noise floor | no SSS: mean |",
        "|---|---|---|---|---|---|---|---|",
    ]
    names = sorted({f.split(".")[0] for f in os.listdir(os.path.join(out, "5.2")) if f.endswith(".rw.npy")})
    for name in (n for n in SCENES if n in names):
        rw52, legacy52 = load("5.2", name, "rw"), load("5.2", name, "same_inputs")
        same45, rw45 = load("4.5", name, "same_inputs"), load("4.5", name, "rw")
        lines.append(
            f"| {name} | {mean(rw52):.4f} | {rel_rmse(load('5.2', name, 'rw_seed1'), rw52):.3f} "
            f"| {mean(legacy52):.4f} ({rel_rmse(legacy52, rw52):.3f}) "
            f"| {mean(same45):.4f} ({rel_rmse(same45, legacy52):.3f}) "
            f"| {mean(rw45):.4f} ({rel_rmse(rw45, rw52):.3f}) "
            f"| {rel_rmse(load('4.5', name, 'rw_seed1'), rw45):.3f} | {mean(load('5.2', name, 'no_sss')):.4f} |"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/rw_versions", help="folder for both versions' images and figures")
    parser.add_argument("--samples", type=int, default=64)
    parser.add_argument("--size", type=int, default=32, help="square image size in pixels")
    parser.add_argument("--scenes", default=",".join(SCENES), help="comma-separated sample scenes")
    parser.add_argument("--table", metavar="DIR", help="print the table from DIR (both versions rendered)")
    args = parser.parse_args(argv)
    if args.table:
        print(table(args.table))
        return 0
    render_all(args.out, samples=args.samples, size=args.size, scenes=[s for s in args.scenes.split(",") if s])
    return 0


if __name__ == "__main__":
    sys.exit(main())
