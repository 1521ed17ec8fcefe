"""``blender/prepare.py``: the kernels compiled in a background process after the extension is enabled."""

import os
import subprocess
import sys

import pytest

from sss_lab.blender import prepare
from sss_lab.core import backend

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_nothing_starts_in_background_blender_or_outside_an_installed_extension(tmp_path):
    # The bpy module runs as background Blender, like a farm task: it prepares when told to.
    assert prepare.start("bl_ext.user_default.sss_lab", str(tmp_path)) is None
    assert prepare.start("sss_lab", str(tmp_path)) is None
    assert not prepare.running() and os.listdir(tmp_path) == []


def test_the_background_process_fills_the_cache_under_the_extensions_package_name():
    # As Blender starts it: the package imported from its parent folder under its folder's name
    # (here the repository's; an installed extension's is its id), the cache folder given. It uses
    # this process's cache, so the kernels it compiles are the ones the tests load.
    if backend.compiled() is None:
        pytest.skip(f"Numba cannot load here ({backend.unavailable_reason()})")
    cache = backend.cache_dir()
    parent, name = os.path.split(ROOT)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    proc = subprocess.run(
        [sys.executable, "-c", prepare.CHILD, parent, name, cache],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "combined: compiling or loading its kernels" in proc.stdout
    assert "kernels ready in" in proc.stdout
    from sss_lab.core.prepare import marker_path

    assert os.path.isfile(marker_path())
