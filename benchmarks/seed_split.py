"""A reference spread over tasks by seed against one render of all its samples:
``.venv/bin/python -m benchmarks.seed_split`` (from the repository root).

Builds a sample scene (default ``head_frontlit``), renders N parts of S samples with seeds
1..N (``sss_lab reference``, as farm tasks do), merges them (``core.study.reference``), and renders
the same scene twice more in one piece with N × S samples (seeds 1000 and 1001). Measures, with
the comparison's metric (relative RMSE over the subsurface pixels after 2 × 2 box downsampling,
``core/study/metrics.py``):

- merged against single: within noise when it is about the noise floor;
- the noise floor from the merged reference's two halves (``core.study.reference.noise_floor``);
- the two-seed noise floor of the comparison (single against single), which the halves' floor
  stands for.

Writes ``benchmarks/results/seed_split.json`` and the figure ``docs/images/seed_split.png``
(merged, single, |merged − single| and |single − single| luminance error on one scale).
"""

from __future__ import annotations

import argparse
import os
import tempfile

import numpy as np


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.seed_split", description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="head_frontlit", help="sample scene (default: %(default)s)")
    parser.add_argument("--tasks", type=int, default=8, help="parts N (default: %(default)s)")
    parser.add_argument("--samples", type=int, default=64, help="samples per part S (default: %(default)s)")
    parser.add_argument("--resolution", default="128x128", help="WxH (default: %(default)s)")
    parser.add_argument("--box", type=int, default=2, help="box downsampling of the metric (default: %(default)s)")
    parser.add_argument("--out", default=os.path.join("benchmarks", "results", "seed_split.json"))
    parser.add_argument("--figure", default=os.path.join("docs", "images", "seed_split.png"))
    args = parser.parse_args(argv)

    import bpy

    from benchmarks._common import resolution, write_results
    from sss_lab.blender.reference import render_reference_parts
    from sss_lab.blender.render_passes import render_passes
    from sss_lab.blender.samples import load_sample_scenes
    from sss_lab.core.base.progress import saved_line
    from sss_lab.core.pipeline import sequence as core_sequence
    from sss_lab.core.scene import exr
    from sss_lab.core.study import metrics, png
    from sss_lab.core.study import reference as ref

    size = resolution(parser, args.resolution)
    work = tempfile.mkdtemp(prefix="sss_lab_seed_split_")
    scenes = load_sample_scenes()
    scenes.build(args.scene, os.path.join(work, f"{args.scene}.blend"))
    scene = bpy.context.scene
    total = args.tasks * args.samples

    written = render_reference_parts(
        scene, os.path.join(work, "parts"), seeds=range(1, args.tasks + 1), samples=args.samples, resolution=size
    )
    parts, _ = ref.read_parts([p for p in written if p.endswith(".exr")])
    merged = ref.merge_parts(parts)
    singles = []
    for seed in (1000, 1001):
        (path, _json) = render_reference_parts(
            scene, os.path.join(work, "single"), seeds=[seed], samples=total, resolution=size
        )
        singles.append(exr.read_passes(path)["Combined"])

    # The subsurface pixels, from the Material Index of a 1-sample passes render.
    (passes_path, _json) = render_passes(
        scene, os.path.join(work, "passes"), techniques=["ssss"], samples=1, resolution=size
    )
    desc = core_sequence.load_scene(passes_path)
    index = np.rint(np.nan_to_num(exr.read_passes(passes_path)["Material Index"])).astype(np.int64)
    index = index[..., 0] if index.ndim == 3 else index
    mask = np.isin(index, [m.index for m in desc.materials if m.scatters])

    def rel(a, b):
        return metrics.compare_images(a, b, mask, box=args.box)["rel_rmse"]

    floor = ref.noise_floor(merged, mask, box=args.box)
    data = {
        "scene": args.scene,
        "resolution": list(size),
        "tasks": args.tasks,
        "samples_per_task": args.samples,
        "total_samples": total,
        "metric": f"relative RMSE over the subsurface pixels after {args.box}x{args.box} box downsampling",
        "merged_vs_single": rel(merged.image, singles[0]),
        "merged_vs_second_single": rel(merged.image, singles[1]),
        "noise_floor_from_halves": floor["rel_rmse"],
        "noise_floor_two_seeds": rel(singles[1], singles[0]),
        "one_part_vs_single": rel(parts[0].image, singles[0]),
        "blender": bpy.app.version_string,
    }
    data["ratio_merged_to_floor"] = data["merged_vs_single"] / data["noise_floor_from_halves"]
    write_results(args.out, data)
    for key in (
        "merged_vs_single",
        "merged_vs_second_single",
        "noise_floor_from_halves",
        "noise_floor_two_seeds",
        "one_part_vs_single",
    ):
        print(f"{key:26s} {data[key]:.4f}")

    luma = metrics.LUMA
    err_merged = np.abs(np.nan_to_num(merged.image[..., :3] - singles[0][..., :3]) @ luma)
    err_single = np.abs(np.nan_to_num(singles[1][..., :3] - singles[0][..., :3]) @ luma)
    vmax = float(np.percentile(np.concatenate([err_merged[mask], err_single[mask]]), 99)) if mask.any() else 1.0
    tiles = [
        png.to_display(merged.image),
        png.to_display(singles[0]),
        png.heat(err_merged, vmax=vmax),
        png.heat(err_single, vmax=vmax),
    ]
    png.write_png(args.figure, png.grid(tiles, columns=4))
    print(saved_line(args.figure))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
