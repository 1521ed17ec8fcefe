"""The scan operator and the scene reader behind it."""

import re

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


def test_a_material_set_by_geometry_nodes_is_read_as_cycles_renders_it(addon):
    """A Geometry Nodes Set Material puts a material on the geometry that no slot names: Cycles
    renders it, so the reader finds it; with the modifier off for renders, Cycles does not, and
    neither does the reader."""
    skin = _principled("Skin", 1.0)
    obj = _cube_with(_principled("Plain", 0.0))
    group = bpy.data.node_groups.new("SetSkin", "GeometryNodeTree")
    group.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    group.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    setter = group.nodes.new("GeometryNodeSetMaterial")
    setter.inputs["Material"].default_value = skin
    group.links.new(group.nodes.new("NodeGroupInput").outputs[0], setter.inputs["Geometry"])
    group.links.new(setter.outputs["Geometry"], group.nodes.new("NodeGroupOutput").inputs[0])
    modifier = obj.modifiers.new("SetSkin", "NODES")
    modifier.node_group = group
    assert [m.name for m in sss_materials(bpy.context.scene)] == ["Skin"]
    modifier.show_render = False
    assert sss_materials(bpy.context.scene) == []


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


def _group_with_principled(name):
    """A shader node group holding a Principled BSDF (Weight 1, Radius (1, 0.5, 0.25), Scale from
    the group's input "Scale") that the group outputs."""
    group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    group.interface.new_socket("Scale", in_out="INPUT", socket_type="NodeSocketFloat")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    inside, outside = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    bsdf = group.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.name = "Inner"
    bsdf.inputs["Subsurface Weight"].default_value = 1.0
    bsdf.inputs["Subsurface Radius"].default_value = (1.0, 0.5, 0.25)
    group.links.new(inside.outputs["Scale"], bsdf.inputs["Subsurface Scale"])
    group.links.new(bsdf.outputs[0], outside.inputs["Shader"])
    return group


def test_materials_are_found_and_read_where_cycles_finds_them(addon):
    """A Principled BSDF inside a node group (its Scale from the group node's input), one behind a
    Mix Shader with its Weight and Scale from Value nodes, and one whose Weight (0 in the socket)
    comes from a texture and whose Radius from an RGB node: every one is a subsurface material,
    each input is listed as typed in or linked, and what cannot be read says what is used."""
    scene = bpy.context.scene
    grouped = bpy.data.materials.new("Grouped")
    compat.ensure_node_tree(grouped)
    nodes, links = grouped.node_tree.nodes, grouped.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    node = nodes.new("ShaderNodeGroup")
    node.node_tree = _group_with_principled("SkinGroup")
    node.inputs["Scale"].default_value = 0.03
    links.new(node.outputs["Shader"], nodes["Material Output"].inputs["Surface"])

    mixed = _principled("Mixed", 0.0)
    nodes, links = mixed.node_tree.nodes, mixed.node_tree.links
    bsdf = nodes["Principled BSDF"]
    mix, gloss = nodes.new("ShaderNodeMixShader"), nodes.new("ShaderNodeBsdfGlossy")
    mix.inputs["Fac"].default_value = 0.75
    links.new(gloss.outputs[0], mix.inputs[1])
    links.new(bsdf.outputs[0], mix.inputs[2])
    links.new(mix.outputs[0], nodes["Material Output"].inputs["Surface"])
    for socket, value in (("Subsurface Weight", 0.8), ("Subsurface Scale", 0.05)):
        v = nodes.new("ShaderNodeValue")
        v.name = socket.split()[-1]
        v.outputs[0].default_value = value
        links.new(v.outputs[0], bsdf.inputs[socket])

    textured = _principled("Textured", 0.0)
    nodes, links = textured.node_tree.nodes, textured.node_tree.links
    bsdf = nodes["Principled BSDF"]
    noise, tint = nodes.new("ShaderNodeTexNoise"), nodes.new("ShaderNodeRGB")
    noise.name, tint.name = "Freckles", "Tint"
    tint.outputs[0].default_value = (0.9, 0.4, 0.2, 1.0)
    links.new(noise.outputs["Fac"], bsdf.inputs["Subsurface Weight"])
    links.new(tint.outputs[0], bsdf.inputs["Subsurface Radius"])
    for mat in (grouped, mixed, textured):
        _cube_with(mat)

    found = {m.name: m for m in sss_materials(scene)}
    assert sorted(found) == ["Grouped", "Mixed", "Textured"]
    assert found["Grouped"].subsurface_scale == pytest.approx(0.03)
    assert (found["Mixed"].subsurface_weight, found["Mixed"].subsurface_scale) == pytest.approx((0.8, 0.05))
    assert found["Textured"].subsurface_weight == 1.0
    assert found["Textured"].subsurface_radius == pytest.approx((0.9, 0.4, 0.2))
    # What the reader could not read travels with the scene description (apply and compare say it).
    assert found["Textured"].notes == (
        "Subsurface Weight linked to Noise Texture 'Freckles': read per pixel from the render "
        "(shader AOV 'SSSLab Weight'); 1 until the passes are read",
    )
    assert found["Textured"].per_pixel == ("subsurface_weight",)
    assert found["Grouped"].per_pixel == found["Mixed"].per_pixel == ()
    assert found["Mixed"].notes == (
        "Principled BSDF 'Principled BSDF' reached through Mix Shader 'Mix Shader' (0.75 of the surface)",
    )

    text = "\n".join(scan_report(scene))
    assert "3 subsurface material(s)" in text
    assert "Subsurface Scale: typed in (through Group Input" in text and "'Inner' reached through" in text
    assert "Subsurface Weight: linked to Value 'Weight', 0.8" in text and "0.75 of the surface" in text
    assert (
        "Subsurface Weight: linked to Noise Texture 'Freckles'; read per pixel from the render "
        "(shader AOV 'SSSLab Weight')" in text
    )
    # The RGB node is called "Color" in Blender 5.x's interface, "RGB" in 4.5's.
    assert re.search(r"Subsurface Radius: linked to (RGB|Color) 'Tint', \(0\.9, 0\.4, 0\.2\)", text)


def test_a_group_without_an_output_is_no_subsurface_material_and_breaks_nothing(addon):
    """A node group with a Principled BSDF inside but no Group Output gives the material output
    nothing (Cycles renders no closure there): the material is not a subsurface material, and
    the reader and ``scan`` say so instead of failing; the material beside it is still found."""
    scene = bpy.context.scene
    group = _group_with_principled("Broken")
    group.nodes.remove(next(n for n in group.nodes if n.bl_idname == "NodeGroupOutput"))
    broken = bpy.data.materials.new("Broken")
    compat.ensure_node_tree(broken)
    nodes = broken.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    node = nodes.new("ShaderNodeGroup")
    node.node_tree = group
    broken.node_tree.links.new(node.outputs[0], nodes["Material Output"].inputs["Surface"])
    _cube_with(broken)
    _cube_with(_principled("Skin", 1.0))
    assert [m.name for m in sss_materials(scene)] == ["Skin"]
    text = "\n".join(scan_report(scene))
    assert "1 subsurface material(s)" in text


def test_a_principled_bsdf_on_an_inactive_output_is_not_read(addon):
    """Cycles renders the active Material Output: a Principled BSDF wired to another, inactive one
    (the active one showing a plain Diffuse BSDF) does not make the material a subsurface one."""
    scene = bpy.context.scene
    mat = _principled("TwoOutputs", 1.0)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    inactive = nodes["Material Output"]
    active = nodes.new("ShaderNodeOutputMaterial")
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    links.new(diffuse.outputs[0], active.inputs["Surface"])
    active.is_active_output = True
    assert not inactive.is_active_output and inactive.inputs["Surface"].is_linked
    _cube_with(mat)
    _cube_with(_principled("Skin", 1.0))
    assert [m.name for m in sss_materials(scene)] == ["Skin"]


def test_a_subsurface_weight_above_one_reads_as_cycles_clamps_it(addon):
    """A Value node of 2 into Subsurface Weight: Cycles clamps the mix factor to 1; so does the
    reader, and it says so."""
    mat = _principled("Wax", 0.0)
    nodes = mat.node_tree.nodes
    value = nodes.new("ShaderNodeValue")
    value.outputs[0].default_value = 2.0
    mat.node_tree.links.new(value.outputs[0], nodes["Principled BSDF"].inputs["Subsurface Weight"])
    _cube_with(mat)
    (m,) = sss_materials(bpy.context.scene)
    assert m.subsurface_weight == 1.0
    assert any("Cycles clamps it to 1" in n for n in m.notes), m.notes


def test_demo_names_a_file_given_as_its_folder(tmp_path, capsys):
    from sss_lab.addon.cli import main

    path = tmp_path / "afile"
    path.write_text("x")
    assert main(["demo", "--out", str(path)]) == 2
    assert "is a file; expected a folder" in capsys.readouterr().err
    assert path.read_text() == "x"


def test_scan_writes_what_it_found_and_recommends_as_json(tmp_path, capsys):
    import json

    from sss_lab.addon.cli import main
    from sss_lab.blender.samples import load_sample_scenes

    blend = load_sample_scenes().build("head_frontlit", str(tmp_path / "head.blend"))
    out = tmp_path / "scan.json"
    args = ["scan", blend, "--json", str(out), "--recommend", "--resolution", "24x24", "--samples", "2"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert f"Saved: '{out}'" in printed
    data = json.loads(out.read_text())
    assert [m["name"] for m in data["materials"]] == ["Skin"]
    (choice,) = data["recommendation"]["materials"]
    assert choice["material"] == "Skin" and choice["chosen"] in {k["name"] for k in choice["candidates"]}
    assert "material 'Skin' (pass index 1" in printed and choice["chosen"] in printed  # the same choice said
    assert main(args) == 2  # an existing --json without --overwrite
    assert "exists; refusing to overwrite it" in capsys.readouterr().err
    # By default the candidates are the techniques at their default quality; --auto-rungs adds the rungs.
    assert data["recommendation"]["rungs"] is False
    assert all(" " not in k["name"] for k in choice["candidates"])
    assert main([*args, "--overwrite", "--auto-rungs"]) == 0
    capsys.readouterr()
    with_rungs = json.loads(out.read_text())["recommendation"]
    assert with_rungs["rungs"] is True
    assert any(" " in k["name"] for k in with_rungs["materials"][0]["candidates"])


def test_the_panel_recommends_per_material_and_leaves_the_scene_as_it_was(addon, tmp_path, capfd):
    from sss_lab.blender.samples import load_sample_scenes

    blend = load_sample_scenes().build("head_frontlit", str(tmp_path / "head.blend"))
    bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 32
    nodes = {m.name: len(m.node_tree.nodes) for m in bpy.data.materials if m.node_tree}
    engine = scene.render.engine
    capfd.readouterr()
    assert bpy.ops.sss_lab.recommend(max_error=0.1) == {"FINISHED"}
    printed = capfd.readouterr()
    assert "Skin: use " in printed.out + printed.err  # the verdict, one line per material
    assert (scene.render.resolution_x, scene.render.engine) == (32, engine)
    assert {m.name: len(m.node_tree.nodes) for m in bpy.data.materials if m.node_tree} == nodes
