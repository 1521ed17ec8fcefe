"""``blender/prepare.py``: the kernels compiled in a background process after the extension is enabled."""

import os
import subprocess
import sys

import pytest

import sss_lab
from sss_lab.blender import prepare
from sss_lab.core.compute import backend

ROOT = os.path.dirname(os.path.abspath(sss_lab.__file__))


def test_nothing_starts_in_background_blender_or_outside_an_installed_extension(tmp_path):
    # The bpy module runs as background Blender, like a farm task: it prepares when told to.
    assert prepare.start("bl_ext.user_default.sss_lab", str(tmp_path)) is None
    assert prepare.start("sss_lab", str(tmp_path)) is None
    assert not prepare.running() and os.listdir(tmp_path) == []


def test_the_background_process_fills_the_cache_under_the_packages_own_name():
    # As Blender starts it: the package's full name and folder, the cache folder. Numba's cache
    # refers to the kernels' module by name, so the process imports the package under the name
    # this process has (here ``sss_lab``; in Blender ``bl_ext.<repo>.<id>``, whose parents it
    # makes): the kernels it compiles load here afterwards, in this process's cache.
    if backend.compiled() is None:
        pytest.skip(f"Numba cannot load here ({backend.unavailable_reason()})")
    cache = backend.cache_dir()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    proc = subprocess.run(
        [sys.executable, "-c", prepare.CHILD, sss_lab.__name__, ROOT, cache],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "combined: compiling or loading its kernels" in proc.stdout
    assert "kernels ready in" in proc.stdout
    from sss_lab.core.study.prepare import marker_path, prepare_kernels

    assert os.path.isfile(marker_path())
    prepare_kernels()  # what it cached loads in this process


def test_the_background_process_makes_blenders_parent_packages(tmp_path):
    # Under an extension's name (``bl_ext.<repo>.<id>``), outside Blender: the parents are made, and
    # the package must come from the folder given (a copy of the package's root module here, so
    # that nothing is compiled: the process stops where it checks the folder).
    folder = tmp_path / "user_default" / "sss_lab"
    folder.mkdir(parents=True)
    (folder / "__init__.py").write_text("")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    proc = subprocess.run(
        [sys.executable, "-c", prepare.CHILD, "bl_ext.user_default.sss_lab", str(folder), str(tmp_path / "c")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    # The empty package imports from the right folder; its core is missing, which ends the run.
    assert "No module named 'bl_ext.user_default.sss_lab.core'" in proc.stderr, proc.stderr[-2000:]
    assert "was imported from" not in proc.stderr
