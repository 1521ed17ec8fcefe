"""``match-eevee``: an EEVEE-only branch per material, matched to Cycles' SSS effect
(``blender/match_eevee.py``), that Cycles never reads."""

from __future__ import annotations

import json
import os
import tempfile

import bpy
import numpy as np
import pytest

from sss_lab.addon.cli import main
from sss_lab.blender import match_eevee as match
from sss_lab.blender.describe import bake_distance
from sss_lab.blender.reference_cache import render_combined
from sss_lab.blender.samples import load_sample_scenes
from sss_lab.blender.state import SceneState
from sss_lab.core.base.errors import InputError
from sss_lab.core.scene import exr
from sss_lab.core.study import eevee_match

pytestmark = pytest.mark.slow

SMALL = dict(resolution=(32, 32), cycles_samples=16, pass_samples=4, eevee_samples=2)


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scenes")
    scenes = load_sample_scenes()
    return {name: scenes.build(name, str(folder / f"{name}.blend")) for name in ("head_frontlit", "asset_head")}


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    """One render cache for every match of head_frontlit at ``SMALL``'s settings in this module
    (the API's and the command's): a later match renders the scene as authored again (it removes
    the earlier branch before it renders), so it reads the earlier one's frames."""
    return str(tmp_path_factory.mktemp("match_cache"))


def _open(path):
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    return bpy.context.scene


def _cycles(scene):
    """Cycles' image of the scene at a fixed seed (the scene left as it was)."""
    with tempfile.TemporaryDirectory() as folder, SceneState() as state:
        path = os.path.join(folder, "cycles.exr")
        render_combined(scene, samples=4, seed=3, resolution=(32, 32), path=path, state=state)
        return exr.read_passes(path)["Combined"].copy()


def _tagged(material):
    return sorted(n.name for n in material.node_tree.nodes if n.get(match.EEVEE_TAG))


def _counts():
    return {m.name: len(m.node_tree.nodes) for m in bpy.data.materials if m.node_tree}, len(bpy.data.node_groups)


def test_the_match_adds_an_eevee_branch_that_cycles_never_reads(blends, renders):
    scene = _open(blends["head_frontlit"])
    skin = bpy.data.materials["Skin"]
    before_cycles, before_counts = _cycles(scene), _counts()
    settings = match.MatchSettings(**SMALL, cache_dir=renders)
    result = match.match_eevee(scene, settings, log=None)
    r = result["materials"]["Skin"]
    assert r["skipped"] is None, r
    # Kept only where it comes closer to Cycles' SSS effect than EEVEE as authored.
    assert r["removed_after"] > r["removed_before"]
    label = (f"{r['k']:g}" if r["k"] in eevee_match.K_GRID else f"{r['k']:.4g}") + (" view" if r["view"] else "")
    assert label in r["errors_by_k"], (label, r["errors_by_k"])
    if r["view"]:  # the branch reads the view angle: Geometry -> |Normal . Incoming| -> ramp -> Base Color
        ramps = [n for n in skin.node_tree.nodes if n.bl_idname == "ShaderNodeValToRGB" and n.get(match.EEVEE_TAG)]
        assert len(ramps) == 1 and len(ramps[0].color_ramp.elements) == 7
    assert json.loads(skin[match.MATCH_KEY])["removed_after"] == r["removed_after"]
    tree = skin.node_tree
    eevee_out = tree.get_output_node("EEVEE")
    assert eevee_out.get(match.EEVEE_TAG) and eevee_out.target == "EEVEE"
    # The baked map feeds EEVEE's Thickness as an object-space length: D sqrt(1 - translucency) / scale.
    assert r["thickness"] and "translucency" in r["thickness"]
    length = eevee_out.inputs["Thickness"].links[0].from_node
    assert length.get(match.EEVEE_TAG) and length.operation == "MULTIPLY"
    assert length.inputs[1].default_value == pytest.approx(bake_distance(scene, skin), rel=1e-6)  # scale 1
    assert length.inputs[0].links[0].from_node.operation == "SQRT"
    assert not tree.get_output_node("CYCLES").get(match.EEVEE_TAG)
    # Cycles renders exactly what it rendered before (same seed, same pixels).
    np.testing.assert_array_equal(_cycles(scene), before_cycles)
    # A second match replaces the first; removing it leaves the material as it was.
    tagged = _tagged(skin)
    again = match.match_eevee(scene, settings, log=None)["materials"]["Skin"]
    assert (again["k"], again["view"], again["removed_after"]) == (r["k"], r["view"], r["removed_after"])
    assert _tagged(skin) == tagged
    assert match.remove_match(skin) and not _tagged(skin) and match.MATCH_KEY not in skin.keys()
    assert _counts() == before_counts
    assert not match.remove_match(skin)


def test_a_grouped_textured_shader_is_copied_for_eevee_and_the_original_left_alone(blends):
    """The asset head's skin: a node group holding the Principled BSDF, its Base Color an image
    texture, behind a Mix Shader with a glossy coat. The branch copies the Mix Shader and the
    group (as a group of its own), multiplies the linked Base Color there, and changes nothing
    Cycles reads."""
    _open(blends["asset_head"])
    skin = next(m for m in bpy.data.materials if m.name.startswith("Skin"))
    groups_before = {g.name: len(g.nodes) for g in bpy.data.node_groups}
    sources = match.add_branch(skin)
    assert len(sources) == 1 and sources[0].groups  # found inside the copied group
    group = sources[0].groups[-1].node_tree
    assert group.name.endswith("(EEVEE)") and group.get(match.EEVEE_TAG)
    node = sources[0].node
    d_now = np.array([0.001, 0.0004, 0.0002])
    match.set_branch(sources[0], d_now, (0.6, 0.4, 0.3), 2 * d_now, (1.2, 1.0, 0.8))
    color = node.inputs["Base Color"]
    multiply = color.links[0].from_node
    assert multiply.bl_idname == "ShaderNodeVectorMath" and multiply.get(match.EEVEE_TAG)
    np.testing.assert_allclose(tuple(multiply.inputs[1].default_value), (1.2, 1.0, 0.8), rtol=1e-6)
    # Setting again changes the same node's factor, adds nothing.
    match.set_branch(sources[0], d_now, (0.6, 0.4, 0.3), d_now, (1.0, 1.0, 1.0))
    assert color.links[0].from_node == multiply
    np.testing.assert_allclose(tuple(multiply.inputs[1].default_value), (1.0, 1.0, 1.0))
    # The original group is untouched; the copy goes with the branch.
    assert {g.name: len(g.nodes) for g in bpy.data.node_groups if not g.get(match.EEVEE_TAG)} == groups_before
    assert match.remove_match(skin)
    assert {g.name: len(g.nodes) for g in bpy.data.node_groups} == groups_before


def test_a_material_with_its_own_eevee_output_is_refused_by_name(blends):
    _open(blends["head_frontlit"])
    skin = bpy.data.materials["Skin"]
    own = skin.node_tree.nodes.new("ShaderNodeOutputMaterial")
    own.target = "EEVEE"
    with pytest.raises(InputError, match=r"material 'Skin' already has an output for EEVEE \('Material Output.001'\)"):
        match.add_branch(skin)
    assert not _tagged(skin)


def test_bad_settings_are_named():
    with pytest.raises(InputError, match="cycles_samples: expected an integer >= 1, got 0"):
        match.MatchSettings(cycles_samples=0).validate()
    with pytest.raises(InputError, match="eevee_samples: expected an integer >= 1"):
        match.MatchSettings(eevee_samples=-2).validate()


def test_the_command_writes_the_matched_file_and_removes_a_match(blends, renders, tmp_path, capsys):
    src = blends["head_frontlit"]
    out = tmp_path / "matched.blend"
    args = ["match-eevee", src, "--out", str(out), "--resolution", "32x32", "--samples", "16"]
    before = sorted(os.listdir(renders))
    more = ["--pass-samples", "4", "--eevee-samples", "2", "--cache", renders, "--json", str(tmp_path / "m.json")]
    code = main([*args, *more])
    printed = capsys.readouterr().out
    assert code == 0 and f"Saved: '{out}'" in printed and "reproduces" in printed
    # --cache keeps the renders there (and nothing else: the passes are not kept).
    kept = sorted(os.listdir(renders))
    assert kept and set(before) <= set(kept) and not any(name.startswith("passes") for name in kept)
    assert json.loads((tmp_path / "m.json").read_text())["materials"]["Skin"]["skipped"] is None
    # An existing output is refused without --overwrite, before anything renders.
    assert main([*args, "--eevee-samples", "2"]) == 2
    assert "exists; refusing to overwrite it" in capsys.readouterr().err
    bare = tmp_path / "bare.blend"
    assert main(["match-eevee", str(out), "--out", str(bare), "--remove"]) == 0
    assert "removed the EEVEE branch of 1 material(s): Skin" in capsys.readouterr().out
    # A --cache that cannot be a folder is named before anything renders.
    assert main([*args, "--out", str(tmp_path / "other.blend"), "--cache", str(out)]) == 2
    assert f"--cache '{out}' is a file; expected a folder for the renders" in capsys.readouterr().err
    _open(str(bare))
    assert not _tagged(bpy.data.materials["Skin"])


def test_the_panel_matches_and_removes_in_one_undoable_step_each(addon, blends):
    scene = _open(blends["head_frontlit"])
    scene.render.resolution_x = scene.render.resolution_y = 32  # the operator renders at the scene's size
    scene.eevee.taa_render_samples = 2  # and with the scene's EEVEE samples
    skin = bpy.data.materials["Skin"]
    assert not bpy.ops.sss_lab.remove_eevee_match.poll()  # nothing to remove yet
    assert bpy.ops.sss_lab.match_eevee(cycles_samples=16) == {"FINISHED"}
    assert _tagged(skin) and bpy.ops.sss_lab.remove_eevee_match.poll()
    assert bpy.ops.sss_lab.remove_eevee_match() == {"FINISHED"}
    assert not _tagged(skin) and match.MATCH_KEY not in skin.keys()
