"""The extension as Blender users get it: one zip per platform built and validated with Blender's
own builder, the Linux x64 one installed from the zip, enabled, used, disabled — leaving nothing
registered. (The wheels come from the build's cache outside the repository: no download after
the first build on a machine.)"""

import os
import subprocess
import sys
import tomllib
import zipfile

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


with open(os.path.join(ROOT, "blender_manifest.toml"), "rb") as _fh:
    PLATFORMS = tomllib.load(_fh)["platforms"]


@pytest.fixture(scope="module")
def built_zips():
    proc = subprocess.run(
        [sys.executable, os.path.join(ROOT, "tools", "build_extension.py")], capture_output=True, text=True, cwd=ROOT
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    saved = [
        line.split("Saved: '", 1)[1].rsplit("' (", 1)[0]
        for line in proc.stdout.splitlines()
        if line.startswith("Saved: ")
    ]
    # One zip per platform, each validated by the builder's validator (build_extension.py fails otherwise),
    # for every Blender, per Blender version, and NumPy-only.
    assert len(saved) == 4 * len(PLATFORMS) == 24
    return {
        (variant, p): next(
            z for z in saved if os.path.basename(z) == f"sss_lab-0.1.0{variant}-{p.replace('-', '_')}.zip"
        )
        for variant in ("", "-blender4.5", "-blender5.2", "-numpy")
        for p in PLATFORMS
    }


@pytest.fixture(scope="module")
def built_zip(built_zips):
    return built_zips[("", "linux-x64")]


def _manifest(path):
    return tomllib.loads(zipfile.ZipFile(path).read("blender_manifest.toml").decode())


def test_per_version_and_numpy_zips_hold_only_what_their_blender_runs(built_zips):
    for platform in ("linux-x64", "windows-x64", "macos-arm64"):
        for variant, py, vmin, vmax in (
            ("-blender4.5", "cp311", "4.5.0", "5.0.0"),
            ("-blender5.2", "cp313", "5.1.0", None),
        ):
            path = built_zips[(variant, platform)]
            assert {w.split("-")[1] for w in _wheels(path)} == {py}, (variant, platform)
            m = _manifest(path)
            assert (m["blender_version_min"], m.get("blender_version_max")) == (vmin, vmax)
        assert _wheels(built_zips[("-numpy", platform)]) == ["openexr-cp311", "openexr-cp313"]
    # The download goal: Blender 5.2 on Linux x64 with the compiled kernels, at most 70 MB
    # (both Pythons' wheels made it 131 MB).
    assert os.path.getsize(built_zips[("-blender5.2", "linux-x64")]) <= 70e6


def _wheels(path):
    return sorted(
        n.split("/")[-1].split("-")[0] + "-" + n.split("-")[2]
        for n in zipfile.ZipFile(path).namelist()
        if n.endswith(".whl")
    )


def test_each_platform_zip_holds_its_own_wheels_for_both_pythons(built_zips):
    full = ["llvmlite-cp311", "llvmlite-cp313", "numba-cp311", "numba-cp313", "openexr-cp311", "openexr-cp313"]
    for platform in ("windows-x64", "macos-arm64", "linux-x64", "linux-arm64"):
        assert _wheels(built_zips[("", platform)]) == full, platform
    # Numba publishes no wheels for macOS x64, nor for Windows arm64 on Python 3.11: NumPy runs there.
    assert _wheels(built_zips[("", "windows-arm64")]) == [
        "llvmlite-cp313",
        "numba-cp313",
        "openexr-cp311",
        "openexr-cp313",
    ]
    assert _wheels(built_zips[("", "macos-x64")]) == ["openexr-cp311", "openexr-cp313"]
    names = zipfile.ZipFile(built_zips[("", "linux-x64")]).namelist()
    assert any("manylinux" in n and "x86_64" in n for n in names) and not any(
        "win_" in n or "macosx" in n for n in names
    )


def test_zip_holds_the_extension_but_no_tooling(built_zip):
    names = zipfile.ZipFile(built_zip).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names
    assert (
        any(n.startswith("core/") for n in names)
        and "core/compute/jit.py" in names
        and "core/techniques/burley/_kernels.py" in names
    )
    tooling = ("tests/", "sample_blends/", "benchmarks/", "tools/", "farm/", ".ci/", ".venv/", ".venv-4.5/", "Makefile")
    for excluded in tooling:
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
        # The compiled kernels cache in the extension's user directory, never in its own folder.
        backend = sys.modules[MODULE + ".core.compute.backend"]
        user_dir = bpy.utils.extension_path_user(MODULE, path="numba")
        assert backend.cache_dir() == user_dir and os.path.isdir(user_dir)
        package_dir = os.path.dirname(sys.modules[MODULE].__file__)
        assert not os.path.commonpath([user_dir, package_dir]) == package_dir
    finally:
        bpy.ops.preferences.addon_disable(module=MODULE)
    assert MODULE not in bpy.context.preferences.addons
    assert registered_sss_lab_names() == []
    bpy.ops.extensions.package_uninstall(repo_index=_user_repo_index(), pkg_id="sss_lab")


def _user_repo_index():
    repos = bpy.context.preferences.extensions.repos
    return next(i for i, repo in enumerate(repos) if repo.module == "user_default")
