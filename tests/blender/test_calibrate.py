"""Fit to Cycles in Blender: calibrate renders, fits, stores the values on the materials, the
scene description reads them back, Clear Fit removes them, and bad input changes nothing.
Small and quick: the backlit_thin sample scene (128 x 128) at 8 samples."""

import bpy
import pytest

from sss_lab.addon.cli import main
from sss_lab.addon.cli_demo import load_sample_scenes
from sss_lab.blender import calibrate as cal
from sss_lab.blender.describe import sss_materials
from sss_lab.core.errors import InputError


@pytest.fixture(scope="module")
def backlit(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scenes")
    return load_sample_scenes().build("backlit_thin", str(folder / "backlit_thin.blend"))


def _state(scene):
    r, c = scene.render, scene.cycles
    return (r.resolution_x, r.resolution_y, c.samples, c.seed, c.use_adaptive_sampling, r.image_settings.file_format)


def test_calibrate_stores_the_fit_and_the_description_reads_it(backlit):
    bpy.ops.wm.open_mainfile(filepath=backlit)
    scene = bpy.context.scene
    before = _state(scene)
    data = cal.calibrate(scene, techniques=("burley", "combined"), samples=8, pass_samples=8, log=lambda _l: None)
    assert _state(scene) == before
    names = {m.name for m in sss_materials(scene)}
    # Every material and technique is either fitted or named on one line with the reason.
    for material in names:
        for technique in ("burley", "combined"):
            fitted = any(r["material"] == material and r["technique"] == technique for r in data["results"])
            named = any(f"'{material}'" in p and technique in p for p in data["problems"])
            assert fitted != named, (material, technique, data["problems"])
    assert data["results"], data["problems"]
    for r in data["results"]:
        mat = bpy.data.materials[r["material"]]
        assert r["heldout_after"] < r["heldout_before"]
        assert list(mat[f"sss_lab_fit_{r['technique']}_gain"]) == pytest.approx(r["params"]["gain"])
        described = next(m for m in sss_materials(scene) if m.name == r["material"])
        assert described.fit[r["technique"]]["d_scale"] == pytest.approx(r["params"]["d_scale"])
    # Clear Fit: back to the unfitted mapping.
    mat = bpy.data.materials[data["results"][0]["material"]]
    assert cal.clear_fit(mat)
    assert not any(k.startswith(cal.PREFIX) for k in mat.keys())
    assert next(m for m in sss_materials(scene) if m.name == mat.name).fit == {}


def test_a_hand_edited_value_out_of_bounds_is_named():
    mat = bpy.data.materials.new("Edited")
    cal.write_fit(mat, "burley", {"gain": (1.0, 1.0, 1.0), "d_scale": 1.0})
    mat["sss_lab_fit_burley_d_scale"] = 9.0  # the panel's soft limits do not stop a script
    with pytest.raises(ValueError, match="material 'Edited' burley fitted d_scale: 9.0 is outside 0.25..4"):
        cal.read_fit(mat)


def test_bad_input_changes_nothing(backlit, tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    with pytest.raises(InputError, match="has no active camera"):
        cal.calibrate(scene)
    bpy.ops.wm.open_mainfile(filepath=backlit)
    with pytest.raises(InputError, match="methods: no fit exists for 'blur'"):
        cal.calibrate(bpy.context.scene, techniques=("blur",))
    # The command line refuses to overwrite its input and writes nothing for a scene without SSS.
    assert main(["calibrate", backlit, "--out", backlit]) == 2
    bpy.ops.wm.read_factory_settings(use_empty=True)
    plain = str(tmp_path / "plain.blend")
    bpy.ops.wm.save_as_mainfile(filepath=plain)
    assert main(["calibrate", plain, "--out", str(tmp_path / "out.blend")]) == 2
    assert not (tmp_path / "out.blend").exists()


def _fits(scene):
    return {
        m.name: sorted(k for k in bpy.data.materials[m.name].keys() if k.startswith(cal.PREFIX))
        for m in sss_materials(scene)
    }


def test_fit_to_cycles_runs_modal_and_esc_leaves_the_materials_unchanged(backlit, modal):
    """The panel's operator as a modal job: three steps (render, passes, fit) with progress; Esc
    after the first render leaves every material and the render settings as they were."""
    from sss_lab.operators.fit import SSS_LAB_OT_fit_to_cycles

    bpy.ops.wm.open_mainfile(filepath=backlit)
    scene = bpy.context.scene
    before, fits = _state(scene), _fits(scene)
    assert not any(fits.values())
    window = modal.Window()
    context = modal.context(window)
    op = modal.driver(SSS_LAB_OT_fit_to_cycles, samples=8, confirmed=True)
    assert op.invoke(context, modal.event("NONE")) == {"RUNNING_MODAL"}
    assert window.progress == [("begin", 0, 3)]
    assert window.status[-1].startswith("Fit to Cycles 1/3: Cycles random walk, 8 samples")
    assert op.modal(context, modal.event("TIMER")) == {"RUNNING_MODAL"}  # the random-walk render
    assert window.progress[-1] == ("update", 1) and window.status[-1].startswith("Fit to Cycles 2/3: passes")
    assert op.modal(context, modal.event("ESC")) == {"CANCELLED"}
    assert window.timers == [] and window.progress[-1] == ("end",) and window.status[-1] is None
    assert "cancelled" in op.reports[-1][1]
    assert _fits(scene) == fits and _state(scene) == before
    # Run to the end: one TIMER event per step; the fits are on the materials.
    op = modal.driver(SSS_LAB_OT_fit_to_cycles, samples=8, confirmed=True)
    assert op.invoke(context, modal.event("NONE")) == {"RUNNING_MODAL"}
    assert op.modal(context, modal.event("TIMER")) == {"RUNNING_MODAL"}
    assert op.modal(context, modal.event("TIMER")) == {"RUNNING_MODAL"}
    assert op.modal(context, modal.event("TIMER")) == {"FINISHED"}, op.reports
    assert any(_fits(scene).values()) and _state(scene) == before
