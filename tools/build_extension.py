"""Build and validate the SSS Lab extension zips, one per platform, with Blender's own builder.

The wheels the manifest lists (Numba, llvmlite and OpenEXR for Python 3.13 and 3.11 on each
platform) are downloaded once into a cache outside the repository (``SSS_LAB_WHEEL_CACHE``, by
default the user's cache folder ``.../sss_lab/wheels``), so that a fresh clone on the same
machine, CI's included, builds without downloading; they are linked (or copied) into ./wheels,
where the builder expects them. Then ``blender_ext.py build --split-platforms`` and ``validate``
for each zip — the builder that ships inside the bpy wheel, the same code as
``blender --command extension build``. Prints ``Saved: '<zip>'`` per zip.

Besides the zips for every supported Blender (both Pythons' wheels), it builds one set per Blender
version with only the wheels of the Python that version runs (``VERSIONS``: half the download for
a user of one Blender), and NumPy-only zips (OpenEXR's wheels, no Numba): each from a copy
of the extension whose manifest names just those wheels and Blender versions, validated alike.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
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


#: Per Blender version: the wheels' Python tag and the Blender versions it runs (the maximum not
#: included). Blender 5.1 moved from Python 3.12 to 3.13; 4.5 LTS runs 3.11.
VERSIONS = {"blender4.5": ("cp311", "4.5.0", "5.0.0"), "blender5.2": ("cp313", "5.1.0", None)}
#: The manifest's own files and folders a staged copy leaves out (the builder would too).
_NOT_STAGED = {".git", ".venv", ".venv-4.5", "dist", "out", "build", "wheels", "tests", "benchmarks", "tools"}


def _variant_manifest(text: str, wheels: list[str], vmin: str, vmax: str | None, all_platforms: bool) -> str:
    """The manifest ``text`` with only ``wheels``, Blender ``vmin`` up to ``vmax`` and, for a zip
    without wheels (``all_platforms``), no platform list (one zip runs everywhere)."""
    text = re.sub(r"(?ms)^wheels = \[.*?^\]\n", "wheels = [\n" + "".join(f'  "{w}",\n' for w in wheels) + "]\n", text)
    text = re.sub(r'(?m)^blender_version_min = ".*"$', f'blender_version_min = "{vmin}"', text)
    if vmax:
        text = re.sub(r'(?m)^(blender_version_min = ".*")$', rf'\1\nblender_version_max = "{vmax}"', text)
    if all_platforms:
        text = re.sub(r"(?m)^platforms = \[.*\]\n", "", text)
    return text


def build_variant(label: str, tool: str, dist: str, manifest: dict, wheels: list[str], vmin: str, vmax) -> list[str]:
    """Build and validate ``label``'s zips from a staged copy of the extension; their paths."""
    with open(os.path.join(ROOT, "blender_manifest.toml"), encoding="utf-8") as fh:
        text = fh.read()
    stem = f"{manifest['id']}-{manifest['version']}"
    with tempfile.TemporaryDirectory(prefix="sss_lab_ext_") as stage:
        source = os.path.join(stage, "source")
        shutil.copytree(
            ROOT,
            source,
            ignore=lambda folder, names: [
                n
                for n in names
                if (folder == ROOT and n in _NOT_STAGED) or n in ("__pycache__",) or n.endswith(".egg-info")
            ],
        )
        for rel in wheels:
            target = os.path.normpath(os.path.join(source, rel))
            os.makedirs(os.path.dirname(target), exist_ok=True)
            try:
                os.link(os.path.normpath(os.path.join(ROOT, rel)), target)
            except OSError:
                shutil.copyfile(os.path.normpath(os.path.join(ROOT, rel)), target)
        with open(os.path.join(source, "blender_manifest.toml"), "w", encoding="utf-8") as fh:
            fh.write(_variant_manifest(text, wheels, vmin, vmax, all_platforms=not wheels))
        out = os.path.join(stage, "dist")
        os.makedirs(out)
        build = [sys.executable, tool, "build", "--source-dir", source, "--output-dir", out]
        if wheels:
            build.append("--split-platforms")
        if subprocess.run(build, stdout=subprocess.DEVNULL).returncode != 0:
            raise RuntimeError(f"blender_ext.py build of the {label} zips failed")
        made = []
        for name in sorted(os.listdir(out)):
            target = os.path.join(dist, name.replace(stem, f"{stem}-{label}", 1))
            os.replace(os.path.join(out, name), target)
            if subprocess.run([sys.executable, tool, "validate", target], stdout=subprocess.DEVNULL).returncode != 0:
                raise RuntimeError(f"blender_ext.py validate {os.path.basename(target)} failed")
            made.append(target)
    return made


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
    try:
        for label, (py, vmin, vmax) in VERSIONS.items():
            wheels = [w for w in manifest.get("wheels", []) if f"-{py}-" in os.path.basename(w)]
            zips += build_variant(label, tool, dist, manifest, wheels, vmin, vmax)
        exr_only = [w for w in manifest.get("wheels", []) if os.path.basename(w).lower().startswith("openexr-")]
        zips += build_variant("numpy", tool, dist, manifest, exr_only, manifest["blender_version_min"], None)
    except (OSError, RuntimeError) as exc:
        return fail(str(exc))
    for zip_path in zips:
        print(f"Saved: '{os.path.abspath(zip_path)}' ({os.path.getsize(zip_path) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
