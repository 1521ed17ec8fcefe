"""The scan operator and the scene reader behind it."""

import bpy
import pytest

from sss_lab.blender import compat
from sss_lab.blender.describe import describe_scene, sss_materials
from sss_lab.blender.scan import scan_report


def _principled(name, weight, method="RANDOM_WALK"):
    mat = bpy.data.materials.new(name)
    compat.ensure_node_tree(mat)
    node = mat.node_tree.nodes["Principled BSDF"]
    node.subsurface_method = method
    node.inputs["Subsurface Weight"].default_value = weight
    node.inputs["Subsurface Scale"].default_value = 0.02
    node.inputs["Subsurface Radius"].default_value = (1.0, 0.5, 0.25)
    return mat


def _cube_with(material):
    mesh = bpy.data.meshes.new(material.name)
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(material.name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def test_scene_without_sss_says_so(addon):
    _cube_with(_principled("Plastic", 0.0))
    assert sss_materials(bpy.context.scene) == []
    assert "no material with subsurface scattering" in scan_report(bpy.context.scene)[0]
    assert bpy.ops.sss_lab.scan_scene() == {"FINISHED"}


def test_sss_materials_are_read_with_their_method_and_radius(addon):
    _cube_with(_principled("Wax", 1.0, method="BURLEY"))
    _cube_with(_principled("Plastic", 0.0))
    (wax,) = sss_materials(bpy.context.scene)
    assert (wax.name, wax.method, wax.index) == ("Wax", "BURLEY", 1)
    # Blender stores the inputs as float32: relative precision 6e-8, so 1e-6 is generous.
    assert wax.radius == pytest.approx(tuple(r * 0.02 for r in (1.0, 0.5, 0.25)), rel=1e-6)


def test_describe_scene_needs_a_camera(addon):
    with pytest.raises(ValueError, match="no active camera"):
        describe_scene(bpy.context.scene)


def test_scan_recommend_renders_small_passes_and_leaves_the_scene_as_it_was(tmp_path, capsys):
    from sss_lab.addon.cli import main
    from sss_lab.blender.samples import load_sample_scenes

    blend = load_sample_scenes().build("backlit_thin", str(tmp_path / "backlit_thin.blend"))
    before = open(blend, "rb").read()
    assert main(["scan", blend, "--recommend", "--resolution", "48x48", "--samples", "4"]) == 0
    out = capsys.readouterr().out
    scene = bpy.context.scene
    r = scene.render
    assert (r.resolution_x, r.resolution_y) == (128, 128)  # the render's size was put back
    assert open(blend, "rb").read() == before  # the file is only read
    assert "Recommendations (passes rendered at 48x48, 4 samples" in out
    for m in sss_materials(scene):
        assert f"material {m.name!r}" in out
    assert out.count("=> ") == len(sss_materials(scene))
    assert "light from behind B" in out and "diffusion D" in out
    # Each choice is no SSS or a run auto knows: a technique at one rung of its quality ladder.
    from sss_lab.core.pipeline import auto

    for line in out.splitlines():
        if line.strip().startswith("=> "):
            chosen = line.strip()[3:].split(":", 1)[0]
            assert chosen == auto.NONE or auto.options_of(chosen) is not None, line
