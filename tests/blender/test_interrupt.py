"""Ctrl-C during a Cycles render, a comparison and a thickness bake (addon/interrupt.py): the
command stops within seconds with exit status 130, the input .blend is untouched, finished
frames are kept whole, and no temporary file is left. Each job is set up to run for minutes,
so that a stop within seconds can only come from the interrupt."""

import hashlib
import os
import signal
import subprocess
import sys
import time

import bpy
import pytest

from sss_lab.blender import compat
from sss_lab.core.scene.exr import read_passes

#: Seconds from SIGINT to the end of the process: the grace period (2 s) plus the exit itself,
#: with room for a loaded 2-core machine.
STOP_WITHIN = 8.0


@pytest.fixture(scope="module")
def cube_blend(tmp_path_factory):
    """Blender's default cube with a subsurface material, saved as a .blend."""
    path = tmp_path_factory.mktemp("interrupt") / "cube.blend"
    bpy.ops.wm.read_factory_settings(use_empty=False)
    material = bpy.data.materials.new("Skin")
    compat.ensure_node_tree(material)
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Subsurface Weight"].default_value = 1.0
    bsdf.inputs["Subsurface Scale"].default_value = 0.1
    bpy.data.objects["Cube"].data.materials[0] = material  # the faces use slot 0
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _interrupt(argv, *, when_line=None, after=None, signum=signal.SIGINT):
    """Run ``python -m sss_lab ARGV``, send SIGINT when stdout shows ``when_line`` (then wait
    ``after`` s) or ``after`` s after the start; (exit status, seconds to stop, stdout, stderr)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "sss_lab", *map(str, argv)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    seen = []
    if when_line is not None:
        for line in proc.stdout:
            seen.append(line)
            if when_line in line:
                break
        else:
            pytest.fail(f"the job ended before {when_line!r}: {''.join(seen)[-500:]} {proc.stderr.read()[-500:]}")
    time.sleep(after or 0.0)
    assert proc.poll() is None, "the job ended before the interrupt"
    proc.send_signal(signum)
    sent = time.monotonic()
    out, err = proc.communicate(timeout=300)
    return proc.returncode, time.monotonic() - sent, "".join(seen) + out, err


def _temporaries(folder):
    return [os.path.join(r, n) for r, _, names in os.walk(folder) for n in names if ".tmp" in n]


@pytest.mark.parametrize(
    ("signum", "name"), [(signal.SIGINT, "Ctrl-C"), (signal.SIGTERM, "SIGTERM"), (signal.SIGHUP, "SIGHUP")]
)
def test_render_stops_and_keeps_the_finished_frame(cube_blend, tmp_path, signum, name):
    """Ctrl-C, a farm manager cancelling a task (SIGTERM) and a closed terminal (SIGHUP) stop the
    same way: exit 130, the finished frame kept whole, no temporary file, the signal named."""
    before = _digest(cube_blend)
    out = tmp_path / "passes"
    # 10000 samples: about 3 s a frame on an idle machine (3000 took about 1 s, which let frame 2
    # finish before a 1 s interrupt), longer under load; the interrupt comes 0.2 s into frame 2,
    # so frame 2 cannot finish first, and frames 2 and 3 would take far longer than STOP_WITHIN.
    code, stopped, stdout, err = _interrupt(
        ["render", cube_blend, "--out", out, "--frames", "1-3", "--resolution", "48x48", "--pass-samples", "10000"]
        + ["--methods", "ssss,burley"],
        when_line="frame 1 done",
        after=0.2,
        signum=signum,
    )
    assert code == 130, err
    assert stopped < STOP_WITHIN
    assert f"interrupted ({name})" in err and "Traceback" not in err and err.count("\n") == 1
    assert sorted(os.listdir(out)) == ["passes_0001.exr", "passes_0001.json"]
    assert read_passes(out / "passes_0001.exr").shape == (48, 48)  # the finished frame is whole
    assert _temporaries(tmp_path) == []
    assert _digest(cube_blend) == before


def test_compare_stops_during_the_reference_render(cube_blend, tmp_path):
    before = _digest(cube_blend)
    out = tmp_path / "report"
    code, stopped, stdout, err = _interrupt(
        ["compare", cube_blend, "--out", out, "--resolution", "48x48", "--reference-samples", "50000"]
        + ["--methods", "ssss,burley"],
        when_line="rendering",
        after=1.0,
    )
    assert code == 130, err
    assert stopped < STOP_WITHIN
    assert "interrupted (Ctrl-C)" in err and "Traceback" not in err
    assert _temporaries(tmp_path) == []
    assert not os.path.exists(out / "metrics.json")
    assert _digest(cube_blend) == before


def test_bake_stops_and_writes_no_blend(cube_blend, tmp_path):
    before = _digest(cube_blend)
    out = tmp_path / "baked.blend"
    code, stopped, stdout, err = _interrupt(
        ["bake-thickness", cube_blend, "--out", out, "--target", "image", "--image-size", "2048", "--samples", "1024"],
        after=4.0,
    )
    assert code == 130, err
    assert stopped < STOP_WITHIN
    assert "interrupted (Ctrl-C)" in err and "Traceback" not in err
    assert not out.exists() and _temporaries(tmp_path) == []
    assert _digest(cube_blend) == before


def _frame_in(filename: str):
    """A live frame whose code claims to come from ``filename``."""
    code = compile("import sys\nframe = sys._getframe()", filename, "exec")
    namespace: dict = {}
    exec(code, namespace)
    return namespace["frame"]


def test_ctrl_c_is_left_to_the_watcher_inside_blender_and_imports():
    """Raised inside Blender's own Python (its start-up scripts, Cycles' engine) or inside an
    import, a KeyboardInterrupt is printed by Blender as a traceback or crashes its start-up; the
    handler leaves those to the watcher (which ends the process within the grace period) and
    raises everywhere else."""
    from sss_lab.addon import interrupt

    scripts = interrupt._blender_scripts()
    assert scripts, "the bpy module's scripts folder was not found"
    inside = os.path.join(scripts[0], "addons_core", "cycles", "__init__.py")
    assert interrupt._handler(signal.SIGINT, _frame_in(inside)) is None
    assert interrupt._handler(signal.SIGINT, _frame_in("<frozen importlib._bootstrap>")) is None
    with pytest.raises(KeyboardInterrupt):
        interrupt._handler(signal.SIGINT, _frame_in(__file__))
