"""Build and validate the SSS Lab extension zips, one per platform, with Blender's own builder.

The wheels the manifest lists (Numba, llvmlite and OpenEXR for Python 3.13 and 3.11 on each
platform) are downloaded once into a cache outside the repository (``SSS_LAB_WHEEL_CACHE``, by
default the user's cache folder ``.../sss_lab/wheels``), so that a fresh clone on the same
machine, CI's included, builds without downloading; they are linked (or copied) into ./wheels,
where the builder expects them. Then ``blender_ext.py build --split-platforms`` and ``validate``
for each zip — the builder that ships inside the bpy wheel, the same code as
``blender --command extension build``. Prints ``Saved: '<zip>'`` per zip.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_WHEEL = re.compile(r"^(?P<name>[^-]+)-(?P<version>[^-]+)-(?P<py>cp\d+)-(?P<abi>[^-]+)-(?P<platform>.+)\.whl$")


def fail(message: str) -> int:
    print(f"build_extension: error: {message}", file=sys.stderr)
    return 1


def blender_ext() -> str:
    import bpy

    path = os.path.join(bpy.utils.system_resource("SCRIPTS"), "addons_core", "bl_pkg", "cli", "blender_ext.py")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path} not found inside the bpy package; is bpy 5.2 installed?")
    return path


def wheel_cache() -> str:
    """Where downloaded wheels are kept between builds (outside the repository)."""
    if os.environ.get("SSS_LAB_WHEEL_CACHE"):
        return os.environ["SSS_LAB_WHEEL_CACHE"]
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or os.path.expanduser("~\\AppData\\Local")
    elif sys.platform == "darwin":
        base = os.path.expanduser("~/Library/Caches")
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return os.path.join(base, "sss_lab", "wheels")


def download(name: str, cache: str) -> None:
    """pip download one wheel file ``name`` (exactly that file) into ``cache``."""
    m = _WHEEL.match(name)
    if m is None:
        raise ValueError(f"manifest wheel {name!r} does not look like a wheel file name")
    print(f"Fetching {name}")
    cmd = [
        sys.executable,
        "-m",
        "pip",
        "download",
        "--disable-pip-version-check",
        "-q",
        "--no-deps",
        "--only-binary=:all:",
        "--platform",
        m["platform"].split(".")[-1],  # a compressed tag set (a.b): pip takes one of them
        "--python-version",
        m["py"][2:],
        "--implementation",
        "cp",
        "--abi",
        m["abi"],
        "-d",
        cache,
        f"{m['name']}=={m['version']}",
    ]
    if subprocess.run(cmd).returncode != 0 or not os.path.isfile(os.path.join(cache, name)):
        raise RuntimeError(f"could not download {name} from the package index (is it reachable from this machine?)")


def fetch_wheels(manifest: dict) -> None:
    """Every wheel of the manifest in ./wheels, from the cache (downloading what it lacks)."""
    cache = wheel_cache()
    os.makedirs(cache, exist_ok=True)
    for rel in manifest.get("wheels", []):
        path = os.path.normpath(os.path.join(ROOT, rel))
        if os.path.isfile(path):
            continue
        name = os.path.basename(path)
        cached = os.path.join(cache, name)
        if not os.path.isfile(cached):
            download(name, cache)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        try:
            os.link(cached, path)  # no copy of some 40 MB per wheel on the same file system
        except OSError:
            shutil.copyfile(cached, path)


def main() -> int:
    with open(os.path.join(ROOT, "blender_manifest.toml"), "rb") as fh:
        manifest = tomllib.load(fh)
    try:
        fetch_wheels(manifest)
        tool = blender_ext()
    except (OSError, RuntimeError, ValueError, ImportError) as exc:
        return fail(str(exc))
    dist = os.path.join(ROOT, "dist")
    os.makedirs(dist, exist_ok=True)
    stem = f"{manifest['id']}-{manifest['version']}"
    for name in os.listdir(dist):
        if name.startswith(stem) and name.endswith(".zip"):
            os.remove(os.path.join(dist, name))  # build products, never inputs
    build = [sys.executable, tool, "build", "--source-dir", ROOT, "--output-dir", dist, "--split-platforms"]
    if subprocess.run(build).returncode != 0:
        return fail("blender_ext.py build failed (see above)")
    zips = [os.path.join(dist, f"{stem}-{p.replace('-', '_')}.zip") for p in manifest["platforms"]]
    for zip_path in zips:
        if not os.path.isfile(zip_path):
            return fail(f"the builder wrote no {zip_path}")
        if subprocess.run([sys.executable, tool, "validate", zip_path]).returncode != 0:
            return fail(f"blender_ext.py validate {os.path.basename(zip_path)} failed (see above)")
    for zip_path in zips:
        print(f"Saved: '{os.path.abspath(zip_path)}' ({os.path.getsize(zip_path) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
