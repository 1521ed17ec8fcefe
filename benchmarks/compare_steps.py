"""How long the interface waits at most while Compare runs modal: the duration of each step of
the comparison job (one Cycles render, one technique run, the report) on the demo scene with the
demo's settings, against the whole job, which ``execute`` used to block for.

    .venv/bin/python -m benchmarks.compare_steps [--scene head_frontlit] [--out DIR]

Prints the step count (announced and run), the whole job's seconds and the five longest steps.
Timings on a shared machine are noisy; the ratio of the longest step to the whole is the point.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.compare_steps", description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default=None, help="sample scene (default: the demo's)")
    parser.add_argument("--out", default=None, help="folder for the scene, cache and report (default: a temporary one)")
    args = parser.parse_args(argv)

    import bpy

    from sss_lab.blender.compare import CompareSettings, compare_job
    from sss_lab.blender.samples import load_sample_scenes
    from sss_lab.core.scene.scene import SUBSURFACE_METHODS

    scenes = load_sample_scenes()
    name = args.scene or scenes.DEFAULT_SCENE
    out = args.out or tempfile.mkdtemp(prefix="sss_lab_compare_steps_")
    os.makedirs(out, exist_ok=True)
    scenes.build(name, os.path.join(out, f"{name}.blend"))
    # The demo's comparison: the default settings, every subsurface method calibrated.
    job = compare_job(
        bpy.context.scene, out, CompareSettings(calibrate_methods=SUBSURFACE_METHODS), log=lambda _line: None
    )
    steps, announced, message = [], 0, "checks and plan"
    start = last = time.perf_counter()
    while True:
        try:
            progress = next(job)
        except StopIteration:
            steps.append((time.perf_counter() - last, message))
            break
        steps.append((time.perf_counter() - last, message))
        announced, message, last = progress.total, progress.message, time.perf_counter()
    whole = time.perf_counter() - start
    steps.sort(reverse=True)
    print(
        f"{name}: {len(steps) - 1} steps run ({announced} announced), whole job {whole:.1f} s, "
        f"longest step {steps[0][0]:.1f} s ({steps[0][1]}); report in {out}"
    )
    for seconds, what in steps[:5]:
        print(f"  {seconds:7.2f} s  {what}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
