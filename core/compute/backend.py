"""Which implementation runs the techniques: the compiled kernels (Numba: each owner's ``_kernels.py``
beside its NumPy reference, on the primitives of ``core/compute/jit.py``) or the NumPy reference, and where the
compiled code is cached (docs/references.md §11).

- ``numba`` (the default when Numba loads): the fused per-pixel kernels.
- ``numpy``: the readable reference, also used wherever Numba cannot load (one line on stderr
  says so, once).
- ``check``: both; the compiled result is returned after it has been compared with the
  reference within ``tolerance`` (``BackendMismatch`` otherwise). The tests run in this mode.

Chosen by the environment variable ``SSS_LAB_BACKEND`` or, in code, ``use("numpy")`` (a context
manager) or ``set_backend``. The on-disk cache of compiled code is never the extension's own
folder (it may not be writable): ``set_cache_dir`` (Blender's extension user directory, set at
registration), else ``NUMBA_CACHE_DIR`` if set, else the user's cache directory.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib
import inspect
import os
import sys
import threading
import time
from collections.abc import Callable
from types import ModuleType
from typing import Any

import numpy as np

from ..base.errors import SSSLabError

ENV = "SSS_LAB_BACKEND"
BACKENDS = ("numba", "numpy", "check")

#: Unit roundoff of float32 (2^-24): each float32 operation is exact to within this, relatively.
U32 = 2.0**-24

_lock = threading.Lock()
_state: dict[str, Any] = {
    "backend": None,
    "cache_dir": None,
    "module": None,
    "error": None,
    "load_s": None,
    "digest": None,
}
_kernels: dict[str, ModuleType] = {}
#: The package's core folder: every ``_kernels.py`` below it and ``compute/jit.py`` are the kernels' sources.
_CORE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_compile_s: dict[str, float] = {}


class BackendMismatch(SSSLabError):
    """The compiled kernel's result differs from the NumPy reference beyond ``tolerance``."""


def _check(name: str) -> str:
    if name not in BACKENDS:
        raise ValueError(f"backend: {name!r} is not one of {', '.join(BACKENDS)}")
    return name


def set_backend(name: str | None) -> None:
    """Choose the backend for this process (None: back to ``SSS_LAB_BACKEND`` or the default)."""
    _state["backend"] = None if name is None else _check(name)


def requested() -> str:
    name = _state["backend"]
    if name is None:
        name = os.environ.get(ENV, "").strip().lower() or "numba"
        if name not in BACKENDS:
            raise ValueError(f"{ENV}: {name!r} is not one of {', '.join(BACKENDS)}")
    return name


def active() -> str:
    """The backend the techniques run on now: ``requested()``, or ``numpy`` when Numba is missing."""
    name = requested()
    if name != "numpy" and compiled() is None:
        return "numpy"
    return name


@contextlib.contextmanager
def use(name: str):
    """``with backend.use("numpy"): ...`` runs the techniques on that backend, then restores."""
    before = _state["backend"]
    set_backend(name)
    try:
        yield
    finally:
        _state["backend"] = before


def user_cache_dir() -> str:
    """The per-user cache folder of the platform (outside Blender), ``.../sss_lab/numba``."""
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or os.path.expanduser("~\\AppData\\Local")
    elif sys.platform == "darwin":
        base = os.path.expanduser("~/Library/Caches")
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return os.path.join(base, "sss_lab", "numba")


def set_cache_dir(path: str) -> None:
    """Where the compiled kernels are cached on disk; takes effect if they are not loaded yet."""
    _state["cache_dir"] = os.fspath(path)


def cache_dir() -> str:
    return _state["cache_dir"] or os.environ.get("NUMBA_CACHE_DIR") or user_cache_dir()


def kernel_sources() -> list[str]:
    """The kernels' source files: ``compute/jit.py`` and every ``_kernels.py`` (or ``_*_kernels.py``)
    under core/, sorted."""
    out = [os.path.join(_CORE, "compute", "jit.py")]
    for folder, dirs, files in os.walk(_CORE):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        out += [os.path.join(folder, f) for f in sorted(files) if f.startswith("_") and f.endswith("kernels.py")]
    return out


def kernel_digest() -> str:
    """A digest of the kernels' sources (their bytes): it names their cache folder."""
    if _state["digest"] is None:
        h = hashlib.sha256()
        for path in kernel_sources():
            h.update(os.path.relpath(path, _CORE).encode() + b"\0")
            with open(path, "rb") as fh:
                h.update(fh.read())
        _state["digest"] = h.hexdigest()[:12]
    return _state["digest"]


def kernel_cache_dir() -> str:
    """The folder of ``cache_dir`` the compiled kernels are cached in: one per name the package is
    imported under and per version of the kernels' sources.

    Numba keys a cache entry by the source file's path, but the entry refers to the kernels'
    module by its name: the same files imported as ``sss_lab`` (a script, a farm node) and as
    ``bl_ext.user_default.sss_lab`` (the extension in Blender) with one cache folder (a shared
    ``NUMBA_CACHE_DIR``) would load each other's entries, and the process in which the other name
    cannot be imported fails with ModuleNotFoundError on its first kernel call. And Numba checks
    an entry against its own file only: a kernel that calls a primitive of ``compute/jit.py`` or
    of another owner's kernels would be loaded stale after that file changed. The digest of every
    kernel source in the folder's name (``kernel_digest``) makes any change compile afresh."""
    package = __name__.rsplit(".", 2)[0]  # e.g. sss_lab.core
    name = "".join(c if c.isalnum() or c in "._-" else "_" for c in package)
    return os.path.join(cache_dir(), f"{name}-{kernel_digest()}")


def _wide_vectors(numba) -> None:
    """Let LLVM vectorize with 512-bit registers on CPUs with AVX-512, where its default tuning
    stops at 256 bits: the kernels' loops over samples and taps then take half the
    instructions (Burley's gather measured 0.45 s -> 0.33 s of CPU at 1080p, docs/references.md
    §11). Numba's code generator is one per process and reads its CPU features once, when it
    first compiles or loads anything: this applies only if that has not happened yet and no
    features were chosen (``NUMBA_CPU_FEATURES``); it changes the tuning, not the instructions
    the CPU supports or any result."""
    from numba.core.registry import cpu_target

    if numba.config.CPU_FEATURES is not None or "_toplevel_target_context" in vars(cpu_target):
        return
    import llvmlite.binding as ll

    features = ll.get_host_cpu_features().flatten()
    if "+avx512f" in features.split(","):
        numba.config.CPU_FEATURES = features + ",-prefer-256-bit"


@contextlib.contextmanager
def _kernel_cache(numba):
    """Numba picks a function's cache folder when it is decorated: point it at ours for the import
    of our kernels only, leaving other users of Numba as they were."""
    path = kernel_cache_dir()
    os.makedirs(path, exist_ok=True)
    before = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = path
    try:
        yield
    finally:
        numba.config.CACHE_DIR = before


def compiled() -> ModuleType | None:
    """The kernels' shared primitives (``core.compute.jit``), loaded with Numba on first use; None
    where Numba cannot load (the NumPy reference runs then)."""
    if _state["module"] is not None or _state["error"] is not None:
        return _state["module"]
    with _lock:
        if _state["module"] is None and _state["error"] is None:
            start = time.perf_counter()
            try:
                import numba

                _wide_vectors(numba)
                with _kernel_cache(numba):
                    from . import jit as module
            except Exception as exc:  # ImportError, or a broken LLVM: fall back, say so once
                _state["error"] = f"{type(exc).__name__}: {exc}"
                print(
                    f"SSS Lab: Numba cannot load ({_state['error']}); using the NumPy implementations", file=sys.stderr
                )
                return None
            _state["load_s"] = time.perf_counter() - start
            _state["module"] = module
    return _state["module"]


def kernels(package: str, name: str = "_kernels") -> ModuleType:
    """The compiled kernels of ``package`` (a full dotted package name: the caller's
    ``__package__``, or ``optics.__name__`` for the shared physics' kernels), its module ``name``,
    imported on first use in the kernels' cache folder. Only on the compiled backend
    (``compiled()`` is not None)."""
    module = f"{package}.{name}"
    found = _kernels.get(module)
    if found is not None:
        return found
    if compiled() is None:
        raise RuntimeError(f"{module}: the compiled kernels are not available ({unavailable_reason()})")
    with _lock:
        if module not in _kernels:
            import numba

            start = time.perf_counter()
            with _kernel_cache(numba):
                _kernels[module] = importlib.import_module(module)
            _state["load_s"] = (_state["load_s"] or 0.0) + time.perf_counter() - start
    return _kernels[module]


def unavailable_reason() -> str | None:
    """Why Numba could not load (None if it did or was not tried yet)."""
    return _state["error"]


def first_call_seconds() -> dict[str, float]:
    """Seconds of each kernel's first call in this process (compiling it, or loading it from
    the cache), and of importing Numba with the kernels (``import``)."""
    out = dict(_compile_s)
    if _state["load_s"] is not None:
        out["import"] = _state["load_s"]
    return out


def _name(kernel) -> str:
    return getattr(kernel, "py_func", kernel).__name__


def run_kernel(kernel, *args) -> None:
    """Call the compiled ``kernel`` (from ``kernels``) with ``args`` in its parallel chunks
    (``core.compute.jit.parallel_chunks``, else ``ROWS_PER_CHUNK`` rows), timing its first call
    in this process."""
    import numba

    from .jit import ROWS_PER_CHUNK

    chunks = getattr(getattr(kernel, "py_func", kernel), "parallel_chunks", ROWS_PER_CHUNK)
    with numba.parallel_chunksize(chunks):
        run_serial(kernel, *args)


def run_serial(kernel, *args):
    """``kernel(*args)``, returning what it returns, timing its first call in this process;
    without ``run_kernel``'s chunk size, which costs more than a kernel without a parallel loop
    spends on the small arrays it is for."""
    name = _name(kernel)
    if name in _compile_s:
        return kernel(*args)
    start = time.perf_counter()
    result = kernel(*args)
    _compile_s[name] = time.perf_counter() - start
    return result


@contextlib.contextmanager
def one_thread():
    """The compiled kernels on one thread within the block: for work made of many calls on small
    arrays, where a second thread only adds the threads' hand-overs and spin-waits (a CPU cost
    that the wall time hides). ``core/study/fit.py`` runs each technique a dozen times on one frame:
    measured per call of SSSS / Burley on the synthetic spheres (``python -m
    benchmarks.fit_threads``, CPU time, the shared 2-core machine under load), two threads -> one:
    33 -> 7 / 52 -> 6 ms at 128 x 128, 54 -> 21 / 63 -> 21 ms at 256, 112 -> 82 / 133 -> 86 ms at
    512, the wall time lower too; on a quiet machine two threads take about half the wall time at
    1080p (README's speed table). ``core.pipeline.auto``'s features read at most 32 x 32 blocks a
    material."""
    if active() == "numpy":
        yield
        return
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(before)


def tolerance(terms: float, magnitude: np.ndarray) -> np.ndarray:
    """Per-pixel bound on |compiled - reference| (float64, the shape of ``magnitude``).

    Both compute the same float32 operations on the same values; they differ in the order of
    the sums, in the exponential and power functions, and where the compiled kernels fuse a
    product into a sum (one rounding instead of two: within the same bound). A float32 sum of
    k terms in any order is within (k - 1) u of the exact sum relative to the sum of the terms'
    magnitudes (u = 2^-24; Higham, "Accuracy and Stability of Numerical Algorithms", 2nd ed.,
    §4.2), and so is each of the two compared results: hence 2 ``terms`` u relative to the ``magnitude`` of the values
    summed (per pixel and channel). Plus 32 u for the functions and the products around the
    sums: the two e^x are within 5 u of each other (2 u and 4 u of the exact value), which a
    cube in the Burley weight makes 15 u, on the weighted sum and on the sum of the weights.
    """
    return (2.0 * terms + 32.0) * U32 * np.abs(np.asarray(magnitude, np.float64))


def local_max(values: np.ndarray, radius: int) -> np.ndarray:
    """Per pixel, the maximum of ``values`` (H, W, C) over a square window of at least
    ``radius`` pixels on each side (non-finite values count as 0)."""
    out = np.where(np.isfinite(values), np.abs(values), 0.0)
    for axis in (0, 1):
        reach = 0
        while reach < min(radius, out.shape[axis]):
            step = min(max(reach, 1), out.shape[axis] - 1)
            if step <= 0:
                break
            shifted = out.copy()
            lo = [slice(None)] * out.ndim
            hi = [slice(None)] * out.ndim
            lo[axis], hi[axis] = slice(step, None), slice(None, -step)
            np.maximum(shifted[tuple(lo)], out[tuple(hi)], out=shifted[tuple(lo)])
            np.maximum(shifted[tuple(hi)], out[tuple(lo)], out=shifted[tuple(hi)])
            out = shifted
            reach += step
    return out


def compare(name: str, reference: np.ndarray, result: np.ndarray, bound: np.ndarray) -> None:
    """Raise ``BackendMismatch`` where ``result`` differs from ``reference`` by more than
    ``bound``; NaN and infinities must sit at the same places with the same values."""
    same_special = np.array_equal(np.isnan(reference), np.isnan(result)) and np.array_equal(
        np.where(np.isinf(reference), reference, 0), np.where(np.isinf(result), result, 0)
    )
    finite = np.isfinite(reference) & np.isfinite(result)
    diff = np.abs(result[finite].astype(np.float64) - reference[finite].astype(np.float64))
    over = diff > bound[finite]
    if not same_special or over.any():
        worst = float((diff - bound[finite]).max()) if diff.size else 0.0
        raise BackendMismatch(
            f"{name}: compiled result differs from the NumPy reference: {int(over.sum())} values beyond the "
            f"float32 bound (worst by {worst:.3g}); NaN/Inf at the same places: {same_special}"
        )


def checked(*, bound: Callable[[dict[str, Any], np.ndarray], np.ndarray]):
    """Decorator for a technique's function: in ``check`` mode, run it on both backends and
    compare them (``compare``, named after the function) within ``bound(arguments, reference)``:
    the per-pixel bound (``tolerance``) its module gives, from the function's keyword arguments
    with their defaults filled in and the NumPy reference's result."""

    def wrap(fn):
        signature = inspect.signature(fn)

        @functools.wraps(fn)
        def run(**kwargs):
            if requested() != "check" or compiled() is None:
                return fn(**kwargs)
            with use("numpy"):
                reference = fn(**kwargs)
            with use("numba"):
                result = fn(**kwargs)
            args = signature.bind(**kwargs)
            args.apply_defaults()
            compare(fn.__name__, reference, result, bound(args.arguments, reference))
            return result

        return run

    return wrap
