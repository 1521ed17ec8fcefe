"""The long jobs as modal operators (operators/modal.py): start, progress, Esc, restore.

Headless Blender has no event loop, so the tests are the event loop (conftest's ``modal``
fixture): they call the operators' own ``invoke`` / ``modal`` / ``cancel`` with timer and Esc
events, as Blender's window manager would, and see the progress and status text each step shows.
"""

import json
import os

import bpy
import pytest

from sss_lab.blender import compat
from sss_lab.blender import render_passes as rp
from sss_lab.operators.comparison import SSS_LAB_OT_compare
from sss_lab.operators.render import SSS_LAB_OT_render_passes

BEFORE = {"Skin": (1.0, False), "Wax": (1.0, True)}
PLAIN = {"Skin": (0.0, False), "Wax": (0.0, False)}


def _files(folder):
    return sorted(os.listdir(folder)) if os.path.isdir(folder) else []


@pytest.fixture
def frames(sss_quads):
    scene = sss_quads
    scene.frame_start, scene.frame_end, scene.frame_current = 1, 3, 2
    scene.render.engine = compat.eevee_engine()  # the user's engine: Render Passes switches to Cycles and back
    scene.sss_lab.render_samples = 2
    scene.sss_lab.technique = "ssss"
    return scene


def test_render_passes_runs_frame_by_frame_and_esc_restores_the_scene_keeping_finished_frames(
    addon, modal, quad_weights, frames, tmp_path
):
    scene, window = frames, modal.Window()
    context = modal.context(window)
    op = modal.driver(SSS_LAB_OT_render_passes, directory=str(tmp_path), use_frame_range=True)

    # Start: checked and planned, nothing rendered or changed yet; the progress counts 3 frames.
    assert op.invoke(context, modal.event("NONE")) == {"RUNNING_MODAL"}
    assert window.progress == [("begin", 0, 3)] and len(window.timers) == 1
    assert window.status[-1] == "Render Passes 1/3: frame 1 (Esc: cancel after this step)"
    assert _files(tmp_path) == [] and scene.render.engine == compat.eevee_engine() and quad_weights() == BEFORE

    # One timer event renders one frame; the scene is changed for the job while it runs.
    assert op.modal(context, modal.event("TIMER")) == {"RUNNING_MODAL"}
    assert _files(tmp_path) == ["passes_0001.exr", "passes_0001.json"]
    assert window.progress[-1] == ("update", 1)
    assert window.status[-1] == "Render Passes 2/3: frame 2 (Esc: cancel after this step)"
    assert scene.render.engine == "CYCLES" and quad_weights() == PLAIN
    # Other input is held back while the job has the scene changed.
    assert op.modal(context, modal.event("LEFTMOUSE")) == {"RUNNING_MODAL"}
    assert _files(tmp_path) == ["passes_0001.exr", "passes_0001.json"]

    # Esc: cancelled between frames; the finished frame stays, the scene is back, the UI cleaned up.
    assert op.modal(context, modal.event("ESC")) == {"CANCELLED"}
    assert _files(tmp_path) == ["passes_0001.exr", "passes_0001.json"]
    assert scene.render.engine == compat.eevee_engine() and quad_weights() == BEFORE and scene.frame_current == 2
    assert window.progress[-1] == ("end",) and window.timers == [] and window.status[-1] is None
    level, message = op.reports[-1]
    assert level == "WARNING" and "cancelled after 1 of 3 steps" in message and "passes_0001.exr" in message
    assert scene.sss_lab.passes_file == ""  # nothing reported as the result


def test_render_passes_modal_run_to_the_end_reports_like_the_blocking_one(addon, modal, quad_weights, frames, tmp_path):
    scene, window = frames, modal.Window()
    context = modal.context(window)
    op = modal.driver(SSS_LAB_OT_render_passes, directory=str(tmp_path), use_frame_range=True)
    assert op.invoke(context, modal.event("NONE")) == {"RUNNING_MODAL"}
    results = [op.modal(context, modal.event("TIMER")) for _ in range(3)]
    assert results == [{"RUNNING_MODAL"}, {"RUNNING_MODAL"}, {"FINISHED"}]
    assert [p for p in window.progress if p[0] == "update"] == [("update", 1), ("update", 2)]
    assert window.progress[-1] == ("end",) and window.timers == [] and window.status[-1] is None
    assert len([f for f in _files(tmp_path) if f.endswith(".exr")]) == 3
    assert scene.sss_lab.passes_file == str(tmp_path / "passes_0003.exr")
    assert scene.render.engine == compat.eevee_engine() and quad_weights() == BEFORE
    assert op.reports[-1] == ("INFO", f"Rendered the ssss passes of 3 frame(s) into {tmp_path}")
    # Headless (no window), bpy.ops runs the same job to its end.
    assert bpy.ops.sss_lab.render_passes(directory=str(tmp_path / "b"), use_frame_range=True) == {"FINISHED"}
    assert _files(tmp_path / "b") == [f for f in _files(tmp_path) if f != "b"]


def test_render_passes_failing_or_ended_by_blender_restores_the_scene(
    addon, modal, quad_weights, frames, tmp_path, monkeypatch
):
    scene, window = frames, modal.Window()
    context = modal.context(window)
    calls = []

    def render(scene):
        calls.append(scene.frame_current)
        if len(calls) == 2:
            raise RuntimeError("the render failed (test)")
        bpy.ops.render.render(write_still=False, scene=scene.name)

    monkeypatch.setattr(rp, "_render", render)
    op = modal.driver(SSS_LAB_OT_render_passes, directory=str(tmp_path), use_frame_range=True)
    op.invoke(context, modal.event("NONE"))
    op.modal(context, modal.event("TIMER"))
    assert op.modal(context, modal.event("TIMER")) == {"CANCELLED"}
    assert op.reports[-1] == ("ERROR", "the render failed (test)")
    assert scene.render.engine == compat.eevee_engine() and quad_weights() == BEFORE
    assert window.timers == [] and window.status[-1] is None
    assert _files(tmp_path) == ["passes_0001.exr", "passes_0001.json"]  # no half-written frame 2

    # Blender ends the operator (a file is loaded): cancel() restores as Esc does.
    monkeypatch.setattr(rp, "_render", lambda scene: bpy.ops.render.render(write_still=False, scene=scene.name))
    op = modal.driver(SSS_LAB_OT_render_passes, directory=str(tmp_path / "c"), use_frame_range=True)
    op.invoke(context, modal.event("NONE"))
    op.modal(context, modal.event("TIMER"))
    assert quad_weights() == PLAIN
    op.cancel(context)
    assert scene.render.engine == compat.eevee_engine() and quad_weights() == BEFORE and window.timers == []


def test_render_passes_bad_input_is_refused_at_start_without_a_timer(addon, modal, quad_weights, frames, tmp_path):
    window = modal.Window()
    (tmp_path / "passes_0001.exr").write_bytes(b"")
    op = modal.driver(SSS_LAB_OT_render_passes, directory=str(tmp_path), use_frame_range=True, overwrite=False)
    assert op.invoke(modal.context(window), modal.event("NONE")) == {"CANCELLED"}
    assert op.reports[-1][0] == "ERROR" and "already exists" in op.reports[-1][1]
    assert window.timers == [] and window.progress == [] and quad_weights() == BEFORE


# -- Compare ------------------------------------------------------------------------------------


def _state(scene, weights):
    """What a comparison must leave as it was."""
    return (scene.render.engine, scene.cycles.samples, scene.cycles.seed, scene.render.resolution_x, weights())


def test_compare_runs_render_by_render_and_esc_keeps_the_cached_references(
    addon, modal, quad_weights, sss_quads, tmp_path, capsys
):
    scene, window = sss_quads, modal.Window()
    context = modal.context(window)
    before = _state(scene, quad_weights)
    props = dict(directory=str(tmp_path), reference_samples=4, pass_samples=2, eevee=False, confirmed=True)
    op = modal.driver(SSS_LAB_OT_compare, **props)

    # Start: 2 references, the passes at 2 and at 8 samples (the bias split), 3 SSSS and 4 Burley
    # runs (STA and the combined technique need a thickness map this scene lacks), Cycles at the
    # passes' 2 samples (the 16/64-sample peers are not below the 4-sample reference), Cycles'
    # Christensen-Burley, the report: 14 steps.
    assert op.invoke(context, modal.event("NONE")) == {"RUNNING_MODAL"}
    assert window.progress == [("begin", 0, 14)]
    assert window.status[-1] == "Compare 1/14: Cycles reference, 4 samples, seed 0 (Esc: cancel after this step)"
    assert not os.path.exists(tmp_path / "cache")

    # One render per timer event: the reference, then the noise-floor reference.
    assert op.modal(context, modal.event("TIMER")) == {"RUNNING_MODAL"}
    assert len([f for f in _files(tmp_path / "cache") if f.endswith(".exr")]) == 1
    assert window.status[-1].startswith("Compare 2/14: Cycles reference, 4 samples, seed 1 (noise floor)")
    assert op.modal(context, modal.event("TIMER")) == {"RUNNING_MODAL"}
    assert window.status[-1].startswith("Compare 3/14: passes, 2 samples")
    assert window.progress[-2:] == [("update", 1), ("update", 2)]
    assert _state(scene, quad_weights) == before  # between renders the scene is the user's

    # Esc: no report, the scene as it was, the two references stay in the cache for the next run.
    assert op.modal(context, modal.event("ESC")) == {"CANCELLED"}
    assert not os.path.exists(tmp_path / "report.html") and _state(scene, quad_weights) == before
    cached = sorted(f for f in _files(tmp_path / "cache") if f.endswith(".exr"))
    assert len(cached) == 2
    assert window.timers == [] and window.status[-1] is None and window.progress[-1] == ("end",)
    assert op.reports[-1][0] == "WARNING" and "cancelled after 2 of 14 steps" in op.reports[-1][1]

    # Run again to the end: the cached references are reused, every step shows, the report is written.
    capsys.readouterr()
    window = modal.Window()
    context = modal.context(window)
    op = modal.driver(SSS_LAB_OT_compare, **props)
    assert op.invoke(context, modal.event("NONE")) == {"RUNNING_MODAL"}
    results = [op.modal(context, modal.event("TIMER")) for _ in range(14)]
    assert results == [{"RUNNING_MODAL"}] * 13 + [{"FINISHED"}]
    assert [p[1] for p in window.progress if p[0] == "update"] == list(range(1, 14))
    assert os.path.isfile(tmp_path / "report.html") and _state(scene, quad_weights) == before
    assert set(cached) <= set(_files(tmp_path / "cache"))
    printed = capsys.readouterr().out
    assert "4 samples seed 0: cached" in printed and "4 samples seed 1: cached" in printed
    assert window.timers == [] and window.status[-1] is None
    assert op.reports[-1][1].startswith(f"Report: {tmp_path / 'report.html'}")


def test_compare_asks_in_a_dialog_first_and_refuses_an_unsaved_relative_folder(addon, modal, sss_quads, tmp_path):
    window = modal.Window()
    window.invoke_props_dialog = lambda operator: window.status.append("dialog") or {"RUNNING_MODAL"}
    op = modal.driver(SSS_LAB_OT_compare)
    assert op.invoke(modal.context(window), modal.event("NONE")) == {"RUNNING_MODAL"}
    assert window.status == ["dialog"] and op.from_dialog and window.timers == []
    # The dialog's OK calls execute(), which starts the run as a new invocation with the dialog's
    # values (headless, that invocation runs it to its end).
    op.directory, op.reference_samples, op.pass_samples = str(tmp_path), 4, 2
    assert op.execute(modal.context(window)) == {"FINISHED"}
    with open(tmp_path / "metrics.json", encoding="utf-8") as fh:
        settings = json.load(fh)["settings"]
    assert (settings["reference_samples"], settings["pass_samples"]) == (4, 2)
    op = modal.driver(SSS_LAB_OT_compare, confirmed=True)  # the default folder "//..." of an unsaved file
    assert op.invoke(modal.context(window), modal.event("NONE")) == {"CANCELLED"}
    assert op.reports == [("ERROR", "Save the .blend file first, or choose an absolute report folder")]
    assert window.timers == []
