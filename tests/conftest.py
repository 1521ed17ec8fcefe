"""Fixtures shared by every test folder. Nothing here imports bpy (tests/blender isolates
Blender's user folders before it is first imported)."""

import functools
import importlib.util
import os
import subprocess
import types

import pytest

_HERE = os.path.dirname(os.path.abspath(__file__))


def _load_chromium_module():
    spec = importlib.util.spec_from_file_location("sss_lab_test_chromium", os.path.join(_HERE, "_chromium.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


chromium_tools = _load_chromium_module()


@pytest.fixture(scope="session")
def chromium():
    """A headless Chromium for the whole session; installed first (tools/ensure_chromium.sh,
    apt-get as root) when it is missing."""
    exe = chromium_tools.find_chromium()
    if exe is None:
        script = os.path.join(os.path.dirname(_HERE), "tools", "ensure_chromium.sh")
        done = subprocess.run(["bash", script], capture_output=True, text=True)
        exe = chromium_tools.find_chromium()
        if exe is None:
            pytest.fail(f"headless Chromium is needed and could not be installed:\n{done.stdout}{done.stderr}")
    with chromium_tools.Chromium(exe) as browser:
        yield browser


@pytest.fixture(scope="session")
def report_page(chromium):
    """``report_page.inspect(folder, screenshots=None)`` opens ``folder``/report.html in Chromium
    at each of ``report_page.viewports``; ``report_page.problems(folder, seen)`` lists what is
    wrong with what it saw (tests/_chromium.py: ``inspect_report``, ``report_problems``)."""
    return types.SimpleNamespace(
        inspect=functools.partial(chromium_tools.inspect_report, chromium),
        problems=chromium_tools.report_problems,
        viewports=chromium_tools.VIEWPORTS,
    )
