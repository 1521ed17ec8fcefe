"""Render passes (blender/render_passes.py), apply in Blender (blender/apply.py), presets and
the ``render`` command, on a tiny scene: 64 x 64 pixels, 4 Cycles samples.

The scene: a UV sphere "Ball" (material "Skin", subsurface, thickness AOV fed by a Value node
of 0.25) in front of a plane "Back" (material "Wax", subsurface with its Subsurface Weight
driven by a link, and a plain material "Wall" on a second plane), lit by a key sun and a back sun. The user's own
settings (Eevee, 4096 adaptive samples, a mist pass, an extra AOV, a light group, a second view
layer, material pass indices 7 and 3) must all be back after each render.
"""

import json
import math
import os

import bmesh
import bpy
import numpy as np
import pytest

from sss_lab.blender import compat
from sss_lab.blender import render_passes as rp
from sss_lab.blender.render_passes import NoSubsurfaceError, needed_passes, render_passes
from sss_lab.core.pipeline.plan import required_passes
from sss_lab.core.pipeline.sequence import load_scene, sidecar_path
from sss_lab.core.scene.exr import read_layers, read_passes
from sss_lab.core.scene.scene import parse_resolution
from sss_lab.core.study.presets import PRESETS, get_preset

SIZE = 64
SAMPLES = 4
ALL = ("sta", "ssss", "burley")


# -- the scene -------------------------------------------------------------------------------
def _principled(mat):
    return mat.node_tree.nodes["Principled BSDF"]


def _material(name, *, weight=1.0, pass_index=0, thickness=None, linked_weight=None):
    mat = bpy.data.materials.new(name)
    compat.ensure_node_tree(mat)
    bsdf = _principled(mat)
    bsdf.inputs["Base Color"].default_value = (0.8, 0.5, 0.4, 1.0)
    bsdf.inputs["Subsurface Weight"].default_value = weight
    bsdf.inputs["Subsurface Scale"].default_value = 0.1
    mat.pass_index = pass_index
    tree = mat.node_tree
    if thickness is not None:
        aov = tree.nodes.new("ShaderNodeOutputAOV")
        aov.aov_name = "Thickness"
        value = tree.nodes.new("ShaderNodeValue")
        value.outputs[0].default_value = thickness
        tree.links.new(value.outputs[0], aov.inputs["Value"])
    if linked_weight is not None:
        value = tree.nodes.new("ShaderNodeValue")
        value.name = "Weight"
        value.outputs[0].default_value = linked_weight
        tree.links.new(value.outputs[0], bsdf.inputs["Subsurface Weight"])
    return mat


def _plane(name, material, location, size=3.0):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=size)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
    mesh.materials.append(material)
    return obj


def build_scene(*, sss=True, thickness=True):
    """The test scene; ``sss`` False: no material scatters; ``thickness`` False: no AOV fed."""
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -4.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = cam

    mesh = bpy.data.meshes.new("Ball")
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=1.0)
    bm.to_mesh(mesh)
    bm.free()
    ball = bpy.data.objects.new("Ball", mesh)
    scene.collection.objects.link(ball)
    mesh.materials.append(
        _material("Skin", weight=1.0 if sss else 0.0, pass_index=7, thickness=0.25 if thickness else None)
    )
    _plane(
        "Back",
        _material("Wax", weight=0.0, pass_index=3, linked_weight=0.5 if sss else None),
        (1.4, 2.0, 0.0),
        size=0.8,
    )
    wall = _plane("Wall", _material("Wall", weight=0.0, pass_index=1), (0.0, 3.0, 0.0), size=6.0)
    wall.pass_index = 5
    if sss:  # the linked Wax weight reads 1.0 unlinked: the scene description lists Wax
        _principled(bpy.data.materials["Wax"]).inputs["Subsurface Weight"].default_value = 1.0

    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    sun.rotation_euler = (0.8, 0.3, 0.0)
    # A back light shining toward the camera (its -Z turned to (0, -0.93, -0.36)), for STA.
    back = bpy.data.objects.new("Back Light", bpy.data.lights.new("Back Light", "SUN"))
    scene.collection.objects.link(back)
    back.rotation_euler = (-1.2, 0.0, 0.0)

    # The user's own settings, which every render must leave as they are.
    layer = scene.view_layers[0]
    layer.use_pass_mist = True
    layer.use_pass_glossy_direct = True
    other = layer.aovs.add()
    other.name, other.type = "Other", "COLOR"
    layer.lightgroups.add(name="Key")
    sun.lightgroup = "Key"
    scene.view_layers.new("Second")
    scene.cycles.samples = 4096
    scene.frame_current = 3
    compat.set_single_image(scene.render.image_settings, "PNG", color_depth="16")
    return scene


# -- snapshot of everything the render touches ----------------------------------------------
def _value(v):
    if isinstance(v, (str, bool, int, set, frozenset)):
        return v
    if isinstance(v, float):
        return round(v, 7)
    return tuple(round(float(x), 7) for x in v)


def _rna_values(owner):
    out = {}
    for prop in owner.bl_rna.properties:
        if prop.type in ("BOOLEAN", "INT", "FLOAT", "ENUM", "STRING") and prop.identifier != "rna_type":
            try:
                out[prop.identifier] = _value(getattr(owner, prop.identifier))
            except (AttributeError, TypeError):
                pass
    return out


def snapshot(scene) -> dict:
    """Every setting, pass flag, material input, link and index the render may change."""
    snap = {
        "frame": (scene.frame_current, scene.frame_subframe),
        "render": _rna_values(scene.render),
        "cycles": _rna_values(scene.cycles),
        "image": _rna_values(scene.render.image_settings),
        "layers": {},
        "materials": {},
        "objects": {o.name: (o.pass_index, o.lightgroup) for o in scene.objects},
    }
    for layer in scene.view_layers:
        snap["layers"][layer.name] = {
            "flags": _rna_values(layer),
            "cycles": _rna_values(layer.cycles),
            "aovs": [(a.name, a.type) for a in layer.aovs],
            "lightgroups": [g.name for g in layer.lightgroups],
        }
    for mat in bpy.data.materials:
        nodes = {}
        for node in mat.node_tree.nodes:
            nodes[node.name] = {
                s.identifier: _value(s.default_value) for s in node.inputs if hasattr(s, "default_value")
            }
        links = sorted(
            (link.from_node.name, link.from_socket.identifier, link.to_node.name, link.to_socket.identifier)
            for link in mat.node_tree.links
        )
        snap["materials"][mat.name] = {"pass_index": mat.pass_index, "nodes": nodes, "links": links}
    return snap


def _assert_same(before, after):
    for key in before:
        assert after[key] == before[key], key


# -- render_passes ---------------------------------------------------------------------------
def test_needed_passes_are_the_union_of_the_techniques():
    names = needed_passes(ALL)
    assert set(names) == set().union(*(required_passes(t) for t in ALL))
    assert len(names) == len(set(names))
    assert needed_passes(["ssss"]) == list(required_passes("ssss"))


@pytest.mark.parametrize("text", ["64x", "x64", "0x10", "axb", "64*64", "1x2x3"])
def test_parse_resolution_rejects_bad_values(text):
    with pytest.raises(ValueError, match="resolution"):
        parse_resolution(text)


def test_parse_resolution():
    assert parse_resolution("640x480") == (640, 480)
    assert parse_resolution((32, 24)) == (32, 24)


def test_passes_written_readable_and_exactly_the_needed_ones(tmp_path, monkeypatch):
    scene = build_scene()
    before = snapshot(scene)
    during = {}
    real_render = rp._render

    def spy(scene_):
        skin = _principled(bpy.data.materials["Skin"])
        wax = bpy.data.materials["Wax"]
        during.update(
            engine=scene_.render.engine,
            adaptive=scene_.cycles.use_adaptive_sampling,
            denoise=scene_.cycles.use_denoising,
            samples=scene_.cycles.samples,
            seed=scene_.cycles.seed,
            skin_weight=skin.inputs["Subsurface Weight"].default_value,
            wax_weight=_principled(wax).inputs["Subsurface Weight"].default_value,
            wax_linked=_principled(wax).inputs["Subsurface Weight"].is_linked,
            indices={m.name: m.pass_index for m in bpy.data.materials},
            second_layer=scene_.view_layers["Second"].use,
            compositing=scene_.render.use_compositing,
        )
        real_render(scene_)

    monkeypatch.setattr(rp, "_render", spy)
    lines = []
    paths = render_passes(scene, tmp_path, techniques=ALL, samples=SAMPLES, seed=11, log=lines.append)
    exr = str(tmp_path / "passes_0003.exr")
    assert paths == [exr, sidecar_path(exr)]
    assert f"Saved: '{exr}'" in lines

    # While rendering: Cycles, fixed samples and seed, SSS as plain diffuse, indices = description.
    assert during["engine"] == "CYCLES" and not during["adaptive"] and not during["denoise"]
    assert (during["samples"], during["seed"]) == (SAMPLES, 11)
    assert during["skin_weight"] == 0.0 and during["wax_weight"] == 0.0 and not during["wax_linked"]
    assert during["indices"] == {"Skin": 1, "Wax": 2, "Wall": 0}  # sss_materials: name order
    assert not during["second_layer"] and not during["compositing"]

    p = read_passes(exr)
    assert set(p.names) == set(needed_passes(ALL))  # exactly: no mist, glossy, Other AOV, light group
    assert p.shape == (SIZE, SIZE)
    description = load_scene(exr)
    by_name = {m.name: m for m in description.materials}
    assert set(by_name) == {"Skin", "Wax"}
    assert (description.camera.width_px, description.camera.height_px) == (SIZE, SIZE)
    assert description.thickness_aov == "Thickness" and description.thickness_convention == "translucency"
    assert description.meta["samples"] == SAMPLES and description.meta["seed"] == 11
    assert description.frame == 3
    index = p["Material Index"]
    assert set(np.unique(index)) <= {0.0, 1.0, 2.0}
    ball = index == by_name["Skin"].index
    wax = index == by_name["Wax"].index
    assert ball.sum() > 500 and wax.sum() > 50  # about 1000 and 100 of the 4096 pixels
    # The Value node writes 0.25, exact in float32; AOVs average the samples, which Cycles'
    # pixel filter (1.5 px wide by default) spreads over neighbouring pixels, while the index is
    # the first sample's: only pixels 2 px inside the ball's index are fully covered by it.
    interior = ball.copy()
    for _ in range(2):
        pad = np.pad(interior, 1)
        interior = interior & pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
    assert interior.sum() > 300
    np.testing.assert_array_equal(p["Thickness"][interior], 0.25)
    # Every rendered object has its own non-zero Object Index (the Wall keeps its 5).
    objects = p["Object Index"]
    assert len(np.unique(objects[ball])) == 1 and objects[ball][0] not in (0, 5)
    assert (objects[index == 0] == 5).any()
    _assert_same(before, snapshot(scene))


def test_only_the_passes_of_the_chosen_technique(tmp_path):
    scene = build_scene(thickness=False)
    before = snapshot(scene)
    paths = render_passes(scene, tmp_path, techniques=["ssss"], samples=SAMPLES, resolution="32x24", log=None)
    p = read_passes(paths[0])
    assert set(p.names) == set(required_passes("ssss"))
    assert p.shape == (24, 32)
    cam = load_scene(paths[0]).camera
    assert (cam.width_px, cam.height_px) == (32, 24)
    _assert_same(before, snapshot(scene))


def test_frames_each_get_a_file_and_their_description(tmp_path):
    scene = build_scene()
    paths = render_passes(scene, tmp_path, techniques=["burley"], frames=[1, 2], samples=SAMPLES, log=None)
    assert [os.path.basename(p) for p in paths] == [
        "passes_0001.exr",
        "passes_0001.json",
        "passes_0002.exr",
        "passes_0002.json",
    ]
    assert [load_scene(paths[i]).frame for i in (0, 2)] == [1, 2]
    assert scene.frame_current == 3


def test_a_scene_without_subsurface_says_so_and_writes_nothing(tmp_path):
    scene = build_scene(sss=False)
    before = snapshot(scene)
    out = tmp_path / "out"
    with pytest.raises(NoSubsurfaceError, match="no material with subsurface scattering"):
        render_passes(scene, out, samples=SAMPLES, log=None)
    assert not out.exists()
    _assert_same(before, snapshot(scene))


def test_sta_without_a_thickness_map_asks_to_bake_first(tmp_path):
    scene = build_scene(thickness=False)
    with pytest.raises(ValueError, match="bake thickness first") as info:
        render_passes(scene, tmp_path, techniques=["sta", "ssss"], samples=SAMPLES, log=None)
    assert "--methods ssss,burley" in str(info.value)
    assert os.listdir(tmp_path) == []


def test_sta_reads_a_baked_thickness_map_and_its_convention(tmp_path):
    from sss_lab.blender.bake import bake_thickness
    from sss_lab.core.scene.thickness import BakeSettings

    scene = build_scene(thickness=False)
    settings = BakeSettings(target="attribute", convention="thickness", samples=4)
    (result,) = bake_thickness(bpy.context, ["Ball"], settings, log=None)
    assert result.status == "baked"
    before = snapshot(scene)
    lines = []
    paths = render_passes(scene, tmp_path, techniques=["sta"], samples=SAMPLES, log=lines.append)
    description = load_scene(paths[0])
    assert description.thickness_convention == "thickness"  # as stored with the baked attribute
    assert "no thickness map in 'Wax': STA reads thickness 0 there" in lines
    p = read_passes(paths[0])
    ball = p["Material Index"] == description.material(1).index
    # Inside AO of a unit sphere at distance D: some rays escape, so the map is above 0 there.
    assert p["Thickness"][ball].max() > 0.0
    _assert_same(before, snapshot(scene))


def test_existing_files_are_not_replaced_without_overwrite(tmp_path):
    scene = build_scene()
    (tmp_path / "passes_0003.json").write_text("{}")
    with pytest.raises(FileExistsError, match="passes_0003.json already exists"):
        render_passes(scene, tmp_path, techniques=["ssss"], samples=SAMPLES, log=None)
    assert sorted(os.listdir(tmp_path)) == ["passes_0003.json"]
    render_passes(scene, tmp_path, techniques=["ssss"], samples=SAMPLES, log=None, overwrite=True)
    assert json.loads((tmp_path / "passes_0003.json").read_text())["frame"] == 3


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"techniques": ["blur"]}, "unknown technique 'blur'"),
        ({"techniques": []}, "at least one"),
        ({"samples": 0}, "samples: expected an integer >= 1"),
        ({"seed": -1}, "seed: expected an integer >= 0"),
        ({"view_layer": "Nope"}, "view layer 'Nope' is not in scene"),
    ],
)
def test_bad_arguments(tmp_path, kwargs, match):
    scene = build_scene()
    with pytest.raises(ValueError, match=match):
        render_passes(scene, tmp_path, log=None, **{"samples": SAMPLES, **kwargs})


def test_a_failure_midway_restores_the_scene(tmp_path, monkeypatch):
    scene = build_scene()
    before = snapshot(scene)
    real_render = rp._render
    calls = []

    def fail_second(scene_):
        calls.append(scene_.frame_current)
        if len(calls) == 2:
            raise RuntimeError("render failed on purpose")
        real_render(scene_)

    monkeypatch.setattr(rp, "_render", fail_second)
    with pytest.raises(RuntimeError, match="on purpose"):
        render_passes(scene, tmp_path, frames=[1, 2, 3], samples=SAMPLES, log=None)
    assert calls == [1, 2]
    # The first frame is complete; nothing of the failed one, no temporary file.
    assert sorted(os.listdir(tmp_path)) == ["passes_0001.exr", "passes_0001.json"]
    _assert_same(before, snapshot(scene))


def test_a_failed_save_leaves_no_partial_file_and_restores(tmp_path, monkeypatch):
    scene = build_scene()
    before = snapshot(scene)

    def broken_verify(path, *args, **kwargs):
        raise RuntimeError(f"{path}: checked and rejected on purpose")

    monkeypatch.setattr(rp, "verify_passes", broken_verify)
    with pytest.raises(RuntimeError, match="on purpose"):
        render_passes(scene, tmp_path, techniques=["ssss"], samples=SAMPLES, log=None)
    assert os.listdir(tmp_path) == []
    _assert_same(before, snapshot(scene))


# -- operators -------------------------------------------------------------------------------
def test_render_operator_writes_and_remembers_the_file(addon, tmp_path):
    scene = build_scene(thickness=False)
    settings = scene.sss_lab
    settings.technique = "ssss"
    settings.render_samples = SAMPLES
    settings.output_dir = str(tmp_path)
    before = snapshot(scene)
    assert bpy.ops.sss_lab.render_passes() == {"FINISHED"}
    exr = str(tmp_path / "passes_0003.exr")
    assert settings.passes_file == exr
    assert set(read_passes(exr).names) == set(required_passes("ssss"))
    _assert_same(before, snapshot(scene))


def test_render_operator_reports_a_scene_without_subsurface(addon, tmp_path):
    scene = build_scene(sss=False)
    scene.sss_lab.output_dir = str(tmp_path / "out")
    assert bpy.ops.sss_lab.render_passes(samples=SAMPLES) == {"CANCELLED"}
    assert not (tmp_path / "out").exists()
    assert scene.sss_lab.passes_file == ""


def test_apply_operator_without_passes_reports(addon):
    build_scene()
    # Headless, bpy.ops raises the operator's ERROR report as a RuntimeError.
    with pytest.raises(RuntimeError, match="no passes file: render the passes first"):
        bpy.ops.sss_lab.apply()
    with pytest.raises(RuntimeError, match="no such passes file"):
        bpy.ops.sss_lab.apply(filepath="/nonexistent/passes.exr")


@pytest.mark.parametrize("technique", ALL)
def test_render_then_apply_round_trip(addon, tmp_path, technique):
    scene = build_scene()
    settings = scene.sss_lab
    settings.technique = technique
    settings.render_samples = SAMPLES
    settings.output_dir = str(tmp_path)
    assert bpy.ops.sss_lab.render_passes() == {"FINISHED"}
    before = snapshot(scene)
    images = set(bpy.data.images)
    assert bpy.ops.sss_lab.apply() == {"FINISHED"}
    out = str(tmp_path / "passes_0003.sss.exr")
    contents = read_layers(out)
    image_layer = f"SSSLab.{technique}.Image"
    assert image_layer in contents.layers and f"SSSLab.{technique}.SSS" in contents.layers
    # The input layers are kept; the rebuilt image differs from Combined only on SSS pixels.
    passes = read_passes(str(tmp_path / "passes_0003.exr"))
    combined = passes["Combined"]
    result = contents.layers[image_layer]
    assert result.shape == combined.shape and np.isfinite(result).all()
    scattering = passes["Material Index"] > 0
    np.testing.assert_array_equal(result[~scattering], combined[~scattering])
    assert not np.array_equal(result[scattering], combined[scattering])
    loaded = [i for i in set(bpy.data.images) - images]
    assert len(loaded) == 1 and os.path.samefile(bpy.path.abspath(loaded[0].filepath), out)
    _assert_same(before, snapshot(scene))
    # Applying again replaces the output (never the input) and reloads the same image.
    assert bpy.ops.sss_lab.apply() == {"FINISHED"}
    assert len(set(bpy.data.images) - images) == 1


# -- presets ---------------------------------------------------------------------------------
def test_presets_carry_their_source():
    for p in PRESETS.values():
        assert p.source
        assert ("Jensen et al. 2001" in p.source) == p.measured
        assert ("artistic choice" in p.source) == (not p.measured)
    assert PRESETS["skin"].measured and PRESETS["marble"].measured
    with pytest.raises(ValueError, match="unknown preset 'glass'; expected one of: skin, marble, wax, jade"):
        get_preset("glass")


def test_preset_operator_sets_the_active_material(addon):
    build_scene()
    scene = bpy.context.scene
    ball = bpy.data.objects["Ball"]
    bpy.context.view_layer.objects.active = ball
    scene.unit_settings.scale_length = 0.01  # 1 unit = 1 cm
    assert bpy.ops.sss_lab.apply_preset(preset="marble") == {"FINISHED"}
    bsdf = _principled(ball.active_material)
    # Jensen et al. 2001 marble: l_d = 8.51 / 5.57 / 3.95 mm, R_d = 0.830 / 0.791 / 0.753.
    np.testing.assert_allclose(bsdf.inputs["Subsurface Radius"].default_value, (1.0, 5.57 / 8.51, 3.95 / 8.51), 1e-6)
    assert bsdf.inputs["Subsurface Scale"].default_value == pytest.approx(0.851, rel=1e-6)  # 8.51 mm in cm
    np.testing.assert_allclose(bsdf.inputs["Base Color"].default_value, (0.830, 0.791, 0.753, 1.0), 1e-6)
    assert bsdf.inputs["Subsurface Weight"].default_value == 1.0


def test_preset_refuses_a_linked_input(addon):
    build_scene()
    plane = bpy.data.objects["Back"]  # Wax: Subsurface Weight driven by a Value node
    bpy.context.view_layer.objects.active = plane
    with pytest.raises(RuntimeError, match="Subsurface Weight driven by a link"):
        bpy.ops.sss_lab.apply_preset(preset="wax")


# -- panel -----------------------------------------------------------------------------------
def test_material_tab_has_the_preset_menu(addon, draw_panels):
    from types import SimpleNamespace

    build_scene()
    rows = draw_panels("material", SimpleNamespace(material=bpy.data.materials["Skin"]))
    assert [(kind, name) for _, kind, name, _ in rows] == [
        ("menu", "sss_lab.apply_preset"),
        ("label", "Skin: not fitted (Fit to Cycles)"),
    ]
    assert draw_panels("material", SimpleNamespace(material=None)) == []  # no material: no panel


@pytest.mark.parametrize("technique", ALL)
def test_panel_draws_the_parameters_and_buttons(addon, draw_panels, technique):
    bpy.context.scene.sss_lab.technique = technique
    rows = draw_panels("render")
    drawn = [name for _, _, name, _ in rows]
    for op in ("sss_lab.bake_thickness", "sss_lab.render_passes", "sss_lab.apply"):
        assert op in drawn
    assert "sss_lab.apply_preset" not in drawn  # a material's preset: in the Material tab
    expected = {
        "sta": {"distortion", "power", "scale", "ambient", "falloff"},
        "ssss": {"n_taps", "kernel_type", "albedo_mode"},
        "burley": {"n_samples", "random_rotation", "albedo_mode"},
    }[technique]
    assert expected <= {name for panel, kind, name, _ in rows if panel == "Parameters" and kind == "prop"}


@pytest.mark.parametrize("technique", ALL)
def test_panel_options_are_taken_by_the_technique(addon, technique):
    """Every option the panel passes is a parameter of the technique function."""
    import inspect

    from sss_lab.core.techniques.registry import get_technique

    params = inspect.signature(get_technique(technique)).parameters
    options = bpy.context.scene.sss_lab.technique_options(technique)
    assert set(options) <= set(params), set(options) - set(params)


# -- command line ----------------------------------------------------------------------------
def _save(tmp_path, **kwargs):
    build_scene(**kwargs)
    path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


def test_cli_render(tmp_path, capsys):
    from sss_lab.addon.cli import main

    blend = _save(tmp_path)
    original = blend.read_bytes()
    out = tmp_path / "out"
    code = main(
        [
            "render",
            str(blend),
            "--out",
            str(out),
            "--frames",
            "1-2",
            "--pass-samples",
            str(SAMPLES),
            "--resolution",
            "32x24",
            "--methods",
            "ssss,burley",
        ]
    )
    stdout = capsys.readouterr().out
    assert code == 0
    for frame in (1, 2):
        exr = out / f"passes_{frame:04d}.exr"
        assert f"Saved: '{exr}'" in stdout and f"Saved: '{out / f'passes_{frame:04d}.json'}'" in stdout
        p = read_passes(exr)
        assert set(p.names) == set(needed_passes(["ssss", "burley"])) and p.shape == (24, 32)
    assert blend.read_bytes() == original
    # The same again refuses to replace the files.
    assert main(["render", str(blend), "--out", str(out), "--frames", "1", "--methods", "ssss"]) == 2
    assert "already exists" in capsys.readouterr().err


def test_cli_render_without_subsurface_writes_nothing(tmp_path, capsys):
    from sss_lab.addon.cli import EXIT_NOTHING_TO_DO, main

    blend = _save(tmp_path, sss=False)
    out = tmp_path / "out"
    assert main(["render", str(blend), "--out", str(out), "--pass-samples", str(SAMPLES)]) == EXIT_NOTHING_TO_DO
    assert "no material with subsurface scattering" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--resolution", "64"], "--resolution"),
        (["--pass-samples", "0"], "--pass-samples: expected an integer >= 1"),
        (["--methods", "blur"], "unknown method 'blur'"),
        (["--frames", "5-1"], "ends before it starts"),
    ],
)
def test_cli_render_bad_arguments(tmp_path, capsys, args, message):
    from sss_lab.addon.cli import main

    blend = _save(tmp_path)
    assert main(["render", str(blend), "--out", str(tmp_path / "out"), *args]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_cli_render_sta_without_thickness(tmp_path, capsys):
    from sss_lab.addon.cli import main

    blend = _save(tmp_path, thickness=False)
    assert main(["render", str(blend), "--out", str(tmp_path / "out"), "--pass-samples", str(SAMPLES)]) == 2
    assert "bake thickness first" in capsys.readouterr().err


def test_a_subsurface_scattering_node_is_read_and_renders_as_diffuse_in_the_passes(addon, sss_quads, tmp_path):
    """A material whose closure is a Subsurface Scattering node (not a Principled BSDF) is a
    subsurface material with the node's method, Scale, Radius and Color; in the passes it renders
    as a Diffuse BSDF of its Color renders, to the bit (Cycles turns a BSSRDF of no radius into a
    diffuse closure), with its Scale's link cut and put back afterwards."""
    from sss_lab.blender.describe import sss_materials
    from sss_lab.blender.state import SceneState

    scene = sss_quads
    tree = bpy.data.materials["Skin"].node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeSubsurfaceScattering")
    node.falloff = "BURLEY"
    node.inputs["Color"].default_value = (0.8, 0.5, 0.3, 1.0)
    node.inputs["Radius"].default_value = (1.0, 0.5, 0.25)
    scale = tree.nodes.new("ShaderNodeValue")
    scale.outputs[0].default_value = 0.1
    tree.links.new(scale.outputs[0], node.inputs["Scale"])
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    skin = next(m for m in sss_materials(scene) if m.name == "Skin")
    assert (skin.method, skin.subsurface_weight, skin.subsurface_scale) == ("BURLEY", 1.0, pytest.approx(0.1))
    assert skin.subsurface_radius == pytest.approx((1.0, 0.5, 0.25)) and skin.base_color == pytest.approx(
        (0.8, 0.5, 0.3)
    )

    def rendered():
        scene.render.filepath = str(tmp_path / "frame.exr")
        scene.render.image_settings.file_format = "OPEN_EXR"
        bpy.ops.render.render(write_still=True)
        return read_layers(str(tmp_path / "frame.exr")).layers

    with SceneState() as st:
        assert "Skin" in rp.zero_subsurface(st, scene)
        assert not node.inputs["Scale"].is_linked and node.inputs["Scale"].default_value == 0.0
        as_passes = rendered()
    assert node.inputs["Scale"].is_linked  # put back
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.8, 0.5, 0.3, 1.0)
    tree.links.new(diffuse.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    with SceneState() as st:
        rp.zero_subsurface(st, scene)  # the other quad's Principled BSDF, as above
        as_diffuse = rendered()
    assert as_passes.keys() == as_diffuse.keys()
    for name, pixels in as_passes.items():
        np.testing.assert_array_equal(pixels, as_diffuse[name], err_msg=name)


def test_a_frame_that_cannot_fit_in_memory_is_refused_before_it_renders(tmp_path, capsys, monkeypatch):
    """A render whose buffers exceed the memory available is refused with the numbers (exit 2),
    nothing written and the .blend unchanged; the same for the Cycles render a comparison takes.
    The available memory is set small here (a 65536 x 65536 frame would need some 200 GB)."""
    from sss_lab.addon.cli import main
    from sss_lab.blender.reference_cache import cached_reference
    from sss_lab.core.base import errors, memory

    blend = _save(tmp_path)
    original = blend.read_bytes()
    # Less than the smallest frame here needs (a four-channel image) or the passes (more channels).
    need = memory.frame_bytes(32, 24, 4)
    monkeypatch.setattr(memory, "available_bytes", lambda: need // 2)
    out = tmp_path / "out"
    args = ["render", str(blend), "--out", str(out), "--pass-samples", "1", "--resolution", "32x24"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "the passes at 32x24: about" in err and "GiB of memory available" in err and "--resolution" in err
    assert not out.exists() or not os.listdir(out)
    assert blend.read_bytes() == original
    bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
    scene = bpy.context.scene
    before = (scene.render.resolution_x, scene.render.resolution_y, scene.cycles.samples)
    with pytest.raises(errors.InputError, match="the Cycles render at 32x24"):
        cached_reference(scene, str(tmp_path / "cache"), samples=1, seed=0, resolution=(32, 24), method=None)
    assert (scene.render.resolution_x, scene.render.resolution_y, scene.cycles.samples) == before
    # With the memory there, the same render runs.
    monkeypatch.setattr(memory, "available_bytes", lambda: None)
    assert main(args) == 0


def test_frame_memory_estimate_and_reading():
    from sss_lab.core.base import errors, memory

    assert memory.frame_bytes(1920, 1080, 10) == 2 * 1920 * 1080 * 10 * 4
    have = memory.available_bytes()
    assert have is None or have > 0
    memory.check_frame(16, 16, 4, "a tiny frame")  # fits on any machine that runs the tests
    if have is not None:
        need = memory.frame_bytes(65536, 65536, 10)
        assert need / 1024**3 == 320.0  # 2 copies x 2^32 pixels x 10 values x 4 bytes
        if need > have:
            with pytest.raises(errors.InputError, match=r"the passes at 65536x65536: about 320\.0 GiB of frame"):
                memory.check_frame(65536, 65536, 10, "the passes")


def test_a_render_region_is_left_out_and_said(tmp_path, capsys):
    """A scene with a Render Region (cropped or not): the passes, the Cycles reference and EEVEE
    cover the whole frame (the techniques gather from around each pixel, and the description's
    camera is the whole frame's), the passes' run says so, and the scene keeps its region."""
    from sss_lab.addon.cli import main
    from sss_lab.blender.reference_cache import cached_reference

    build_scene()
    r = bpy.context.scene.render
    r.use_border, r.use_crop_to_border = True, True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.25, 0.75
    blend = tmp_path / "border.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    out = tmp_path / "out"
    args = ["render", str(blend), "--out", str(out), "--pass-samples", "1", "--resolution", "32x24"]
    assert main([*args, "--methods", "ssss"]) == 0
    assert "Render Region" in capsys.readouterr().out
    (written,) = sorted(out.glob("passes_*.exr"))
    assert read_passes(written).shape == (24, 32)
    bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
    scene = bpy.context.scene
    image, _, _ = cached_reference(scene, str(tmp_path / "cache"), samples=1, seed=0, resolution=(32, 24), method=None)
    assert image.shape[:2] == (24, 32)
    assert scene.render.use_border and scene.render.use_crop_to_border
