"""What SSSS's surface weighting costs: ``python -m benchmarks.ssss_weighting``.

The speed benchmark's SSSS case (``benchmarks/speed.py``: its plane-and-spheres passes at
1920 x 1080, 17 taps, the energy stage left out) on the compiled backend with two threads, with
``weighting="surface"`` (the default) and ``weighting="screen"`` (the paper's filter), full
screen and with the 25 % mask. The four calls alternate within each of ``--repeat`` rounds, so
that a loaded machine slows both alike; the fastest of each is reported with their ratio and the
load average before and after (docs/references.md §3). Writes
``benchmarks/results/ssss_weighting.json``.
"""

from __future__ import annotations

import argparse
import os
import time

from benchmarks import speed
from benchmarks._common import add_options, resolution, write_results
from sss_lab.core.compute import backend
from sss_lab.core.optics import kernels
from sss_lab.core.techniques.ssss.technique import ssss

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "ssss_weighting.json")
WEIGHTINGS = ("screen", "surface")


def run(width: int, height: int, repeat: int) -> dict:
    passes, scene, depth, _, masks = speed.inputs(width, height)
    diffuse, albedo = speed.light_and_albedo(passes)
    kernel = kernels.preintegrated_kernel(17, d_su=speed.D_SU)
    speed.set_threads(2)
    load_before = os.getloadavg()

    def call(mask, weighting):
        args = {"diffuse": diffuse, "albedo": albedo, "depth": depth, "mask": mask, "camera": scene.camera}
        return ssss(**args, kernel=kernel, weighting=weighting, energy="lambert")

    best: dict[tuple[str, str], float] = {}
    with backend.use("numba"):
        for mask in masks.values():
            for weighting in WEIGHTINGS:
                call(mask, weighting)  # compile or load the kernel first
        for _ in range(repeat):
            for name, mask in masks.items():
                for weighting in WEIGHTINGS:
                    start = time.perf_counter()
                    call(mask, weighting)
                    key = (name, weighting)
                    best[key] = min(best.get(key, float("inf")), time.perf_counter() - start)
    cases = {
        name: {
            **{f"{w}_ms": round(best[(name, w)] * 1e3, 1) for w in WEIGHTINGS},
            "surface_over_screen": round(best[(name, "surface")] / best[(name, "screen")], 3),
        }
        for name in masks
    }
    for name, case in cases.items():
        ratio = case["surface_over_screen"]
        print(f"{name}: screen {case['screen_ms']} ms, surface {case['surface_ms']} ms, ratio {ratio}")
    return {
        "command": "python -m benchmarks.ssss_weighting",
        "resolution": [width, height],
        "repeat": repeat,
        "threads": 2,
        "load_average_before": [round(v, 2) for v in load_before],
        "load_average_after": [round(v, 2) for v in os.getloadavg()],
        "cases": cases,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.ssss_weighting", description=__doc__.split("\n\n")[0])
    add_options(parser, repeat=7, results=RESULTS)
    args = parser.parse_args(argv)
    width, height = resolution(parser, args.resolution)
    write_results(args.out, run(width, height, args.repeat))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
