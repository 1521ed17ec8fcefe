"""The compiled kernels prepared in a background process once the extension is enabled.

With an empty kernel cache, the first Apply of each technique waits while Numba compiles its
kernels (``core/study/prepare.py``), and Blender does not redraw meanwhile. When the extension is
registered in an interactive Blender and this version's kernels are not in the cache yet,
``start`` runs ``core.study.prepare.prepare_kernels`` in a separate Python process (Blender's own
interpreter, ``sys.executable``, at low priority), which fills the same cache folder; Blender
goes on at once, and the panel says while it runs. Nothing starts in background Blender
(``blender -b``: a render-farm task or a script, which can run ``sss_lab prepare`` itself), for
a package that is not an installed extension (the tests, the bpy module), where Numba is not
installed, or when the cache already holds this version's kernels. The process writes what it
did to ``prepare.log`` in the cache folder.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

#: What the background process runs: ``argv`` the package's full name (``bl_ext.<repo>.<id>`` in
#: Blender) and folder, and the cache folder. It imports the package under the name Blender gives
#: it, making the parent packages Blender makes itself (``bl_ext``, ``bl_ext.<repo>``): Numba's
#: cache refers to the kernels' module by name, and an entry written under another name fails to
#: load in Blender. It lowers its own priority (a fork-time hook is not safe in Blender's threads).
CHILD = """
import importlib, os, sys, types
if hasattr(os, "nice"):
    os.nice(10)
package, folder, cache = sys.argv[1:4]
parts = package.split(".")
for i in range(1, len(parts)):
    name = ".".join(parts[:i])
    try:
        importlib.import_module(name)
    except ImportError:
        module = types.ModuleType(name)
        module.__path__ = [os.path.dirname(folder)] if i == len(parts) - 1 else []
        sys.modules[name] = module
if len(parts) == 1:
    sys.path.insert(0, os.path.dirname(folder))
root = importlib.import_module(package)
if os.path.dirname(os.path.abspath(root.__file__)) != os.path.abspath(folder):
    sys.exit(f"{package} was imported from {root.__file__}, not from {folder}")
backend = importlib.import_module(package + ".core.compute.backend")
backend.set_cache_dir(cache)
prepare = importlib.import_module(package + ".core.study.prepare")
result = prepare.prepare_kernels(log=print)
print(f"{len(result['kernels'])} kernels ready in {result['seconds']:.1f} s")
"""

_state: dict = {"process": None}


def running() -> bool:
    """Whether the background process this Blender started is still compiling."""
    process = _state["process"]
    return process is not None and process.poll() is None


def start(package: str, cache_dir: str) -> subprocess.Popen | None:
    """Start the background process for the extension's package ``package`` (``bl_ext.<repo>.<id>``)
    and the kernel cache ``cache_dir``, unless one of the cases of the module docstring holds;
    returns it (None when nothing was started)."""
    import bpy

    from ..core.compute import backend
    from ..core.study.prepare import marker_path

    if bpy.app.background or not package.startswith("bl_ext.") or running():
        return None
    if importlib.util.find_spec("numba") is None:
        return None
    backend.set_cache_dir(cache_dir)
    if os.path.isfile(marker_path()):
        return None
    folder = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # the extension's folder
    os.makedirs(cache_dir, exist_ok=True)
    env = dict(os.environ)
    # Blender's own module folders and the extension's wheels (Numba, llvmlite), as this process has them.
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
    flags = 0
    if sys.platform == "win32":
        flags = subprocess.BELOW_NORMAL_PRIORITY_CLASS | subprocess.CREATE_NO_WINDOW
    with open(os.path.join(cache_dir, "prepare.log"), "w", encoding="utf-8") as log:
        _state["process"] = subprocess.Popen(
            [sys.executable, "-c", CHILD, package, folder, cache_dir],
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            env=env,
            creationflags=flags,
        )
    return _state["process"]
