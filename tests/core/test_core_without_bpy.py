"""core/ must run on a render-farm node without Blender: importing any core module with bpy and
mathutils blocked must work."""

import os
import pkgutil
import subprocess
import sys

import sss_lab.core

CORE_DIR = os.path.dirname(sss_lab.core.__file__)

_BLOCK_AND_IMPORT = """
import importlib, sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('bpy', 'mathutils', 'bmesh', '_bpy'):
            raise ImportError(f'blocked import of {name}')
        return None
sys.meta_path.insert(0, Block())
for name in sys.argv[1:]:
    importlib.import_module(name)
print('imported', len(sys.argv) - 1)
"""


def core_modules():
    """Every module of core/ and its subpackages, by its dotted name."""
    return sorted(m.name for m in pkgutil.walk_packages([CORE_DIR], prefix="sss_lab.core."))


def test_every_core_module_imports_with_bpy_blocked():
    modules = core_modules()
    assert "sss_lab.core.scene.scene" in modules  # the listing itself works
    proc = subprocess.run([sys.executable, "-c", _BLOCK_AND_IMPORT, *modules], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"imported {len(modules)}"


def test_the_blocker_does_block_bpy():
    # Guards the test above against a blocker that blocks nothing.
    proc = subprocess.run([sys.executable, "-c", _BLOCK_AND_IMPORT, "bpy"], capture_output=True, text=True)
    assert proc.returncode != 0
    assert "blocked import of bpy" in proc.stderr


def test_core_sources_never_mention_bpy_imports():
    for m in pkgutil.walk_packages([CORE_DIR], prefix="sss_lab.core."):
        parts = m.name.split(".")[2:]
        path = os.path.join(CORE_DIR, *parts, "__init__.py") if m.ispkg else os.path.join(CORE_DIR, *parts) + ".py"
        with open(path, encoding="utf-8") as fh:
            for number, line in enumerate(fh, 1):
                stripped = line.strip()
                assert not stripped.startswith(("import bpy", "from bpy", "import mathutils", "from mathutils")), (
                    f"{os.path.relpath(path, CORE_DIR)}:{number} imports Blender: {stripped}"
                )
