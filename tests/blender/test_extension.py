"""The extension as Blender users get it: built with Blender's own builder, installed from the
zip, enabled, used, disabled — leaving nothing registered."""

import os
import subprocess
import sys

import _bpy
import bpy
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MODULE = "bl_ext.user_default.sss_lab"


def registered_sss_lab_names():
    ops = [name for name in _bpy.ops.dir() if name.startswith("SSS_LAB_OT_")]
    types = [name for name in dir(bpy.types) if name.startswith(("SSS_LAB_", "SSSLab"))]
    props = ["Scene.sss_lab"] if hasattr(bpy.types.Scene, "sss_lab") else []
    return ops + types + props


@pytest.fixture(scope="module")
def built_zip():
    proc = subprocess.run(
        [sys.executable, os.path.join(ROOT, "tools", "build_extension.py")], capture_output=True, text=True, cwd=ROOT
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    saved = [line.split("Saved: ", 1)[1] for line in proc.stdout.splitlines() if line.startswith("Saved: ")]
    assert len(saved) == 1
    return saved[0]


def test_zip_holds_the_extension_and_wheels_but_no_tooling(built_zip):
    import zipfile

    names = zipfile.ZipFile(built_zip).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names
    assert any(n.startswith("core/") for n in names)
    wheels = [n for n in names if n.startswith("wheels/") and n.endswith(".whl")]
    assert len(wheels) == 6  # Windows x64/arm64, macOS x64/arm64, Linux x64/arm64
    for excluded in ("tests/", "sample_blends/", "benchmarks/", "tools/", ".ci/", ".venv/", "Makefile"):
        assert not any(n.startswith(excluded) for n in names), excluded


def test_install_enable_run_disable_leaves_nothing_registered(built_zip):
    assert registered_sss_lab_names() == []
    result = bpy.ops.extensions.package_install_files(filepath=built_zip, repo="user_default", enable_on_install=True)
    assert result == {"FINISHED"}
    try:
        assert MODULE in bpy.context.preferences.addons
        assert "SSS_LAB_OT_scan_scene" in _bpy.ops.dir()
        assert hasattr(bpy.types.Scene, "sss_lab")
        assert bpy.ops.sss_lab.scan_scene() == {"FINISHED"}
    finally:
        bpy.ops.preferences.addon_disable(module=MODULE)
    assert MODULE not in bpy.context.preferences.addons
    assert registered_sss_lab_names() == []
    bpy.ops.extensions.package_uninstall(repo_index=_user_repo_index(), pkg_id="sss_lab")


def _user_repo_index():
    repos = bpy.context.preferences.extensions.repos
    return next(i for i, repo in enumerate(repos) if repo.module == "user_default")
