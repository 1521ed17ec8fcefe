"""``python -m benchmarks.busy_threads``: the compiled kernels on two threads when the machine's
cores are busy with other work, with OpenMP's waiting threads spinning for a while (its default)
and sleeping at once (``OMP_WAIT_POLICY=PASSIVE``; docs/references.md §11).

Each case runs in a fresh process (OpenMP reads its policy once, when Numba starts its threads):
``core.pipeline.apply.apply`` of ``core.study.synthetic.sphere_scene`` with STA and Burley at the defaults, at
96 x 54, 480 x 270 and 1920 x 1080, two threads, one untimed call then ``--calls`` timed ones;
the fastest and the median call. "twin": while another process applies Burley in a loop with the
same policy (two farm tasks on one node; Blender beside a background job); "busy": while other
processes spin on all cores but one (``--spinners``: a render or another task beside this one);
"quiet": nothing added (the machine as it is: say how loaded it was). The two policies
alternate, ``--rounds`` times each, so that the machine's drift weighs on both alike. Writes
``benchmarks/results/busy_threads.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

from benchmarks._common import write_results

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "busy_threads.json")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SIZES = ((96, 54), (480, 270), (1920, 1080))
TECHNIQUES = ("sta", "burley")

_CASE = """
import json, sys, time
import numba
from sss_lab.core import backend
from sss_lab.core.pipeline.apply import apply
from sss_lab.core.scene.exr import Passes
from sss_lab.core.study.synthetic import sphere_scene
calls = int(sys.argv[1])
out = {}
with backend.use("numba"):
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    for w, h in json.loads(sys.argv[2]):
        arrays, scene = sphere_scene(w, h)
        passes = Passes(arrays)
        for t in json.loads(sys.argv[3]):
            apply(passes, scene, t)
            times = []
            for _ in range(calls):
                start = time.perf_counter()
                apply(passes, scene, t)
                times.append(time.perf_counter() - start)
            times.sort()
            median = times[len(times) // 2]
            out[f"{t} {w}x{h}"] = {"best_ms": round(times[0] * 1e3, 2), "median_ms": round(median * 1e3, 2)}
print(json.dumps({"layer": numba.threading_layer(), "cases": out}))
"""

_SPIN = "while True:\n    pass\n"

#: A twin: another process applying Burley to the sphere scene in a loop with the same policy
#: (two farm tasks on one node, or Blender beside a background job).
_TWIN = """
import sys
from sss_lab.core import backend
from sss_lab.core.pipeline.apply import apply
from sss_lab.core.scene.exr import Passes
from sss_lab.core.study.synthetic import sphere_scene
arrays, scene = sphere_scene(480, 270)
passes = Passes(arrays)
with backend.use("numba"):
    while True:
        apply(passes, scene, "burley")
"""


def _env(policy: str) -> dict:
    """The environment of a process with OpenMP's default waiting ("spin") or the passive one."""
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    if policy == "passive":
        env["OMP_WAIT_POLICY"] = "PASSIVE"
    return env


def _case(policy: str, calls: int, sizes, techniques) -> dict:
    env = _env(policy)
    proc = subprocess.run(
        [sys.executable, "-c", _CASE, str(calls), json.dumps(sizes), json.dumps(techniques)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
        check=True,
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run(rounds: int = 2, calls: int = 15, spinners: int | None = None, sizes=SIZES, techniques=TECHNIQUES, log=print):
    spinners = max(1, (os.cpu_count() or 2) - 1) if spinners is None else spinners
    results: dict = {"load_before": os.getloadavg(), "spinners": spinners, "busy": {}, "twin": {}, "quiet": {}}
    for load in ("twin", "busy", "quiet"):
        for r in range(rounds):
            for policy in ("spin", "passive"):
                procs = []
                if load == "busy":
                    procs = [subprocess.Popen([sys.executable, "-c", _SPIN]) for _ in range(spinners)]
                    time.sleep(0.5)
                elif load == "twin":
                    procs = [subprocess.Popen([sys.executable, "-c", _TWIN], cwd=ROOT, env=_env(policy))]
                    time.sleep(3.0)  # its first frames
                try:
                    case = _case(policy, calls, sizes, techniques)
                finally:
                    for p in procs:
                        p.kill()
                        p.wait()
                results[load].setdefault(policy, []).append(case["cases"])
                results["threading_layer"] = case["layer"]
                log(f"{load:5s} round {r + 1} {policy:7s} " + "  ".join(
                    f"{k} {v['median_ms']:.1f}" for k, v in case["cases"].items()
                ))  # fmt: skip
    results["load_after"] = os.getloadavg()
    return results


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.busy_threads", description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=2, help="alternations of the two policies (default 2)")
    parser.add_argument("--calls", type=int, default=15, help="timed calls per case (default 15)")
    parser.add_argument("--spinners", type=int, default=None, help="busy processes (default: the cores but one)")
    parser.add_argument("--out", default=RESULTS, help=f"JSON output (default {os.path.relpath(RESULTS, ROOT)})")
    args = parser.parse_args(argv)
    results = run(args.rounds, args.calls, args.spinners)
    results["command"] = "python -m benchmarks.busy_threads " + " ".join(argv if argv is not None else sys.argv[1:])
    write_results(args.out, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
