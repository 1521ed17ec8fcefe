"""Blender tests: an isolated Blender user profile, factory settings around each test.

Blender reads its user folders from the environment when bpy is first imported, so they are
pointed at a temporary folder here, before any test module imports bpy.
"""

import os
import shutil
import sys
import tempfile

import pytest

if "bpy" in sys.modules:
    raise RuntimeError("bpy was imported before tests/blender/conftest.py could isolate Blender's user folders")

_USER_ROOT = tempfile.mkdtemp(prefix="sss_lab_blender_user_")
for _var, _sub in (
    ("BLENDER_USER_RESOURCES", "resources"),
    ("BLENDER_USER_CONFIG", "config"),
    ("BLENDER_USER_SCRIPTS", "scripts"),
    ("BLENDER_USER_DATAFILES", "datafiles"),
    ("BLENDER_USER_EXTENSIONS", "extensions"),
):
    os.environ[_var] = os.path.join(_USER_ROOT, _sub)
    os.makedirs(os.environ[_var], exist_ok=True)

bpy = pytest.importorskip("bpy", reason="tests/blender need the bpy module (make test installs it)")


def _factory_reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)


@pytest.fixture(autouse=True)
def factory_settings():
    """Each test starts from, and leaves, Blender's factory settings with an empty scene."""
    _factory_reset()
    yield
    _factory_reset()


@pytest.fixture
def addon():
    """SSS Lab registered from the source tree (the installed-zip path has its own test)."""
    import sss_lab

    sss_lab.register()
    try:
        yield sss_lab
    finally:
        sss_lab.unregister()


def pytest_sessionfinish(session, exitstatus):
    shutil.rmtree(_USER_ROOT, ignore_errors=True)
