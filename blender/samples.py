"""The bundled sample scenes: ``sample_blends/build_scenes.py`` loaded as a module.

The command line's ``demo`` (``addon/cli_demo.py``), the benchmarks and the tests build their
scenes with it: ``load_sample_scenes().build(name, path)``.
"""

from __future__ import annotations

import importlib.util
import os

from ..core.base.errors import InputError

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def load_sample_scenes():
    """The sample-scene builder module (a source checkout only: the extension zip leaves it out)."""
    path = os.path.join(_ROOT, "sample_blends", "build_scenes.py")
    if not os.path.isfile(path):
        raise InputError(f"the sample scenes are not here ({path} is missing); run from a source checkout")
    spec = importlib.util.spec_from_file_location("sss_lab_sample_scenes", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
