"""Why the fit runs the compiled kernels on one thread: ``.venv/bin/python -m benchmarks.fit_threads``.

The fit (``core/study/fit.py``) runs each technique a dozen times on one frame, and its cost is its CPU
time (``benchmarks/fit.py``: process time, all threads). This measures one ``core.pipeline.apply`` call of
SSSS and Burley (their light transport alone, ``energy="lambert"``, what the fit runs per value of
d's scale) on the synthetic spheres of ``core.study.synthetic`` at a few sizes, with Numba's default
number of threads and with one: CPU seconds (process time) and wall seconds, each the fastest of
``--repeat`` rounds of ``--calls`` calls (after an untimed call that loads the kernels). Writes
``benchmarks/results/fit_threads.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results", "fit_threads.json")


def _per_call(run, calls: int, repeat: int) -> tuple[float, float]:
    """(CPU seconds, wall seconds) per call, each the fastest round's."""
    cpu = wall = float("inf")
    for _ in range(repeat):
        c0, w0 = time.process_time(), time.perf_counter()
        for _ in range(calls):
            run()
        cpu = min(cpu, (time.process_time() - c0) / calls)
        wall = min(wall, (time.perf_counter() - w0) / calls)
    return cpu, wall


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.fit_threads", description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="128,256,512", help="square frame sizes in pixels")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--calls", type=int, default=3)
    parser.add_argument("--out", default=RESULTS)
    args = parser.parse_args(argv)
    import numba

    from benchmarks._common import write_results
    from sss_lab.core.compute import backend
    from sss_lab.core.pipeline import apply as core_apply
    from sss_lab.core.scene.exr import Passes
    from sss_lab.core.study.synthetic import sphere_scene

    if backend.active() == "numpy":
        raise SystemExit("benchmarks.fit_threads: Numba is not available; nothing to measure")
    default = numba.get_num_threads()
    rows = []
    for size in (int(v) for v in args.sizes.split(",")):
        arrays, scene = sphere_scene(size, size)
        passes = Passes(arrays)
        for technique in ("ssss", "burley"):
            core_apply.apply(passes, scene, technique, energy="lambert")
            row = {"size": size, "technique": technique}
            for threads in (default, 1):
                numba.set_num_threads(threads)

                def run(p=passes, s=scene, t=technique):
                    core_apply.apply(p, s, t, energy="lambert")

                cpu, wall = _per_call(run, args.calls, args.repeat)
                row[f"threads_{threads}"] = {"cpu_s": cpu, "wall_s": wall}
            numba.set_num_threads(default)
            rows.append(row)
            many, one = row[f"threads_{default}"], row["threads_1"]
            ms = {k: v * 1e3 for k, v in (*many.items(), *((f"one_{k}", v) for k, v in one.items()))}
            print(
                f"{size} px {technique}: {default} threads {ms['cpu_s']:.1f} ms CPU, {ms['wall_s']:.1f} ms wall;"
                f" 1 thread {ms['one_cpu_s']:.1f} ms CPU, {ms['one_wall_s']:.1f} ms wall",
                flush=True,
            )
    write_results(
        args.out,
        {
            "command": "python -m benchmarks.fit_threads " + " ".join(argv if argv is not None else sys.argv[1:]),
            "definition": __doc__.split("\n\n", 1)[1].strip(),
            "machine": {
                "platform": platform.platform(),
                "cpus": os.cpu_count(),
                "note": "shared, loaded 2-core machine",
            },
            "default_threads": default,
            "rows": rows,
        },
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
