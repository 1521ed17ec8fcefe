"""Type-check SSS Lab with mypy (configuration: ``[tool.mypy]`` in pyproject.toml).

The repository root is the package ``sss_lab`` (``package-dir`` in pyproject.toml), which mypy can
only name through a folder that holds it under that name: a temporary folder with a link to the
root. Exit status: mypy's (0 when every checked module passes).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGES = ("core", "blender", "operators", "nodes", "addon")


def main() -> int:
    with tempfile.TemporaryDirectory(prefix="sss_lab_mypy_") as tmp:
        os.symlink(ROOT, os.path.join(tmp, "sss_lab"))
        cmd = [sys.executable, "-m", "mypy", "--config-file", os.path.join(ROOT, "pyproject.toml")]
        cmd += ["--cache-dir", os.path.join(ROOT, ".mypy_cache")]
        for name in PACKAGES:
            cmd += ["-p", f"sss_lab.{name}"]
        return subprocess.call(cmd, cwd=tmp, env={**os.environ, "MYPYPATH": tmp})


if __name__ == "__main__":
    sys.exit(main())
