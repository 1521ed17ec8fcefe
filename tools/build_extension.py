"""Build and validate the SSS Lab extension zip with Blender's own extension builder.

Downloads the OpenEXR wheels the manifest lists (one per platform Blender ships on) into
./wheels, then runs ``blender_ext.py build`` and ``validate`` — the builder that ships inside
the bpy wheel, the same code as ``blender --command extension build``. Prints ``Saved: ZIP``.
"""

from __future__ import annotations

import os
import re
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


def fetch_wheels(manifest: dict) -> None:
    for rel in manifest.get("wheels", []):
        path = os.path.normpath(os.path.join(ROOT, rel))
        if os.path.isfile(path):
            continue
        m = _WHEEL.match(os.path.basename(path))
        if m is None:
            raise ValueError(f"manifest wheel {rel!r} does not look like a wheel file name")
        print(f"Fetching {os.path.basename(path)}")
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
            m["platform"],
            "--python-version",
            m["py"][2:],
            "--implementation",
            "cp",
            "--abi",
            m["abi"],
            "-d",
            os.path.dirname(path),
            f"{m['name']}=={m['version']}",
        ]
        if subprocess.run(cmd).returncode != 0 or not os.path.isfile(path):
            raise RuntimeError(
                f"could not download {os.path.basename(path)} from the package index "
                "(is it reachable from this machine?)"
            )


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
    zip_path = os.path.join(dist, f"{manifest['id']}-{manifest['version']}.zip")
    if os.path.exists(zip_path):
        os.remove(zip_path)  # a build product, never an input
    steps = (
        [sys.executable, tool, "build", "--source-dir", ROOT, "--output-filepath", zip_path],
        [sys.executable, tool, "validate", zip_path],
    )
    for cmd in steps:
        if subprocess.run(cmd).returncode != 0:
            return fail(f"{' '.join(os.path.basename(c) for c in cmd[1:3])} failed (see above)")
    print(f"Saved: {zip_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
