"""A/B of one technique's compiled kernel: this tree's against a git revision's, alternating calls.

On a shared machine a kernel's time drifts by more than the changes worth measuring, between
runs and within one: the two kernels are therefore called one after the other, in alternating
order, in one process, on the arguments the speed benchmark's case hands to the kernel
(``benchmarks/speed.py``, captured from one call of the technique), and the outputs are
compared to the bit. Prints the best and median wall and CPU times of each and their ratios.

    .venv/bin/python -m benchmarks.kernel_ab --base origin/main            # STA, 1080p
    .venv/bin/python -m benchmarks.kernel_ab --base HEAD~1 --threads 1 --mask "25 % mask"

The revision's core/ (its kernels, ``_kernels.py`` beside each owner, and their primitives in
``core/compute/jit.py``) is compiled from a temporary folder, with its own Numba cache there (never
beside the module); revisions before the kernels moved beside their owners cannot be loaded. Arguments are matched by
name, so that a kernel that
gained or lost one can still be compared with its earlier self.
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from benchmarks import speed
from sss_lab.core.compute import backend

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: The technique's kernel: (its package below core, the kernel's name).
KERNELS = {"sta": ("techniques.sta", "sta_kernel")}


def _load_revision(rev: str, folder: str, package: str):
    """The kernels module of ``package`` (below core) at ``rev``, as the module of a copy of that
    revision's core/ in ``folder`` (a package of its own, ``sss_ab_base``), compiled and cached inside ``folder``."""
    base = os.path.join(folder, "sss_ab_base")
    os.makedirs(base)
    archive = subprocess.run(["git", "-C", ROOT, "archive", rev, "core"], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", base], input=archive, check=True)
    with open(os.path.join(base, "__init__.py"), "w") as f:
        f.write("")
    import numba

    before = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = os.path.join(folder, "cache")
    sys.path.insert(0, folder)
    try:
        return importlib.import_module(f"sss_ab_base.core.{package}._kernels")
    finally:
        sys.path.remove(folder)
        numba.config.CACHE_DIR = before


def _caller(kernel, named: dict, chunk: int):
    import numba

    names = list(inspect.signature(kernel.py_func).parameters)
    missing = [n for n in names if n not in named]
    if missing:
        raise SystemExit(f"kernel_ab: the base kernel takes {missing}, which this tree's does not pass (--arg)")

    def call(out):
        args = [out if n == "out" else named[n] for n in names]
        with numba.parallel_chunksize(chunk):
            kernel(*args)

    return call


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.kernel_ab", description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", required=True, help="git revision whose kernel is A (this tree's is B)")
    parser.add_argument("--technique", default="sta", choices=sorted(KERNELS))
    parser.add_argument("--resolution", default="1920x1080", help="WxH (default 1920x1080)")
    parser.add_argument("--mask", default="full screen", help="'full screen' or '25 %% mask'")
    parser.add_argument("--threads", type=int, default=0, help="Numba threads (default: Numba's)")
    parser.add_argument("--calls", type=int, default=30, help="calls of each kernel (default 30)")
    parser.add_argument(
        "--arg", action="append", default=[], metavar="NAME=INT", help="an integer argument this tree's kernel lacks"
    )
    args = parser.parse_args(argv)
    import numba

    if backend.compiled() is None:
        raise SystemExit(f"kernel_ab: Numba cannot load ({backend.unavailable_reason()})")
    if args.threads:
        numba.set_num_threads(args.threads)
    package, name = KERNELS[args.technique]
    width, height = (int(v) for v in args.resolution.lower().split("x"))
    captured: dict = {}
    run_kernel = backend.run_kernel

    def spy(kernel, *kernel_args):
        if kernel.py_func.__name__ == name and not captured:
            captured["args"] = kernel_args
        return run_kernel(kernel, *kernel_args)

    backend.run_kernel = spy
    try:
        cases, masks = speed.cases(width, height)
        cases[args.technique][0](masks[args.mask])
    finally:
        backend.run_kernel = run_kernel
    new = getattr(backend.kernels(f"{backend.__name__.rsplit('.', 2)[0]}.{package}"), name)
    named = dict(zip(inspect.signature(new.py_func).parameters, captured["args"], strict=True))
    for item in args.arg:
        key, _, value = item.partition("=")
        named.setdefault(key, int(value))
    chunk = getattr(new.py_func, "parallel_chunks", backend.compiled().ROWS_PER_CHUNK)
    with tempfile.TemporaryDirectory() as folder:
        base = _load_revision(args.base, folder, package)
        calls = {"A": _caller(getattr(base, name), named, chunk), "B": _caller(new, named, chunk)}
        outs = {k: np.full_like(named["out"], np.nan) for k in calls}
        for k, call in calls.items():
            call(outs[k])  # compiles (or loads) each
        same = np.array_equal(outs["A"], outs["B"], equal_nan=True)
        wall: dict = {"A": [], "B": []}
        cpu: dict = {"A": [], "B": []}
        out = np.empty_like(named["out"])
        for i in range(args.calls):
            for k in ("A", "B") if i % 2 == 0 else ("B", "A"):
                c, s = time.process_time(), time.perf_counter()
                calls[k](out)
                wall[k].append(time.perf_counter() - s)
                cpu[k].append(time.process_time() - c)
    print(
        f"{name} {width}x{height} {args.mask}, {numba.get_num_threads()} thread(s), {args.calls} alternating calls"
        f" each, load average {os.getloadavg()[0]:.2f}; A = {args.base}, B = this tree"
    )
    print(f"outputs equal to the bit: {same}")
    for label, times in (("wall", wall), ("CPU", cpu)):
        a, b = np.array(times["A"]) * 1e3, np.array(times["B"]) * 1e3
        print(
            f"{label}: A best {a.min():.2f} median {np.median(a):.2f} ms | B best {b.min():.2f} median"
            f" {np.median(b):.2f} ms | B/A best {b.min() / a.min():.3f}, median of pairs {np.median(b / a):.3f}"
        )
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
