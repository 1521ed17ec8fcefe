"""Subsurface inputs linked to what the scene reader cannot read as a constant (textures, Math
and Mix nodes, node groups) are rendered by Cycles into shader AOVs beside the passes and read
back per material and per pixel (``core/scene/inputs.py``), on the ``sss_quads`` scene (16 x 16
pixels, 4 samples)."""

import bpy
import numpy as np
import pytest

from sss_lab.blender.describe import sss_materials
from sss_lab.blender.render_passes import render_passes
from sss_lab.core.pipeline import apply as core_apply
from sss_lab.core.pipeline.plan import plan
from sss_lab.core.pipeline.sequence import load_scene
from sss_lab.core.scene.exr import read_passes
from sss_lab.core.scene.inputs import interior, weight_map
from sss_lab.core.scene.passes import INPUT_AOVS


def _mix_colors(tree, a, b, factor):
    """A Mix node (colour mode) of two RGB nodes at ``factor``: a constant the scene reader
    does not evaluate, (1 - factor) a + factor b per channel."""
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.inputs["Factor"].default_value = factor
    for value, socket in ((a, mix.inputs[6]), (b, mix.inputs[7])):
        rgb = tree.nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = (*value, 1.0)
        tree.links.new(rgb.outputs[0], socket)
    return mix.outputs[2]


def _scale_group(factor):
    """A node group whose output is its input "Scale" times ``factor`` (a Math node inside)."""
    group = bpy.data.node_groups.new("ScaleRig", "ShaderNodeTree")
    group.interface.new_socket("Scale", in_out="INPUT", socket_type="NodeSocketFloat")
    group.interface.new_socket("Scale", in_out="OUTPUT", socket_type="NodeSocketFloat")
    inside, outside = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    math = group.nodes.new("ShaderNodeMath")
    math.operation = "MULTIPLY"
    math.inputs[1].default_value = factor
    group.links.new(inside.outputs[0], math.inputs[0])
    group.links.new(math.outputs[0], outside.inputs[0])
    return group


def _tree_sizes():
    trees = [m.node_tree for m in bpy.data.materials if m.node_tree] + list(bpy.data.node_groups)
    return {t.name: (len(t.nodes), len(t.links)) for t in trees}


def test_linked_inputs_are_rendered_per_pixel_and_read_back_exactly(addon, sss_quads, tmp_path):
    """Skin's Base Color from a Mix node of two colours, its Scale from a node group's Math node and
    its Weight from a Checker texture (0 or 1 per check): each is listed per pixel, its AOV is in
    the passes file (and only then), the medians are the values Cycles evaluates (the Mix and the
    Math node's results, to float32 rounding), and the scene's node trees are as they were after."""
    scene = sss_quads
    tree = bpy.data.materials["Skin"].node_tree
    bsdf = tree.nodes["Principled BSDF"]
    tree.links.new(_mix_colors(tree, (0.2, 0.4, 0.6), (0.6, 0.2, 0.2), 0.25), bsdf.inputs["Base Color"])
    rig = tree.nodes.new("ShaderNodeGroup")
    rig.node_tree = _scale_group(4.0)
    rig.inputs["Scale"].default_value = 0.025
    tree.links.new(rig.outputs[0], bsdf.inputs["Subsurface Scale"])
    checker = tree.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 3.0
    checker.inputs["Color1"].default_value = (1.0, 1.0, 1.0, 1.0)
    checker.inputs["Color2"].default_value = (0.0, 0.0, 0.0, 1.0)
    tree.links.new(checker.outputs["Fac"], bsdf.inputs["Subsurface Weight"])

    skin = next(m for m in sss_materials(scene) if m.name == "Skin")
    assert sorted(skin.per_pixel) == ["base_color", "subsurface_scale", "subsurface_weight"]
    before = _tree_sizes()
    exr, _ = render_passes(scene, str(tmp_path), techniques=["burley"], log=None)
    assert _tree_sizes() == before  # the AOV Output nodes are gone again

    passes = read_passes(exr)
    wanted = {INPUT_AOVS[k].name for k in skin.per_pixel}
    assert wanted <= set(passes.names) and INPUT_AOVS["subsurface_radius"].name not in passes.names
    desc = load_scene(exr)
    p = plan(passes, desc, "burley")
    measured = next(mp.material for mp in p.materials if mp.material.name == "Skin")
    assert measured.measured
    assert measured.base_color == pytest.approx((0.3, 0.35, 0.5), abs=1e-6)
    assert measured.subsurface_scale == pytest.approx(0.1, abs=1e-7)
    assert any("read from the render ('SSSLab Scale' AOV): median 0.1 over" in n for n in measured.notes)
    assert "note: Base Color: read from the render ('SSSLab Base Color' AOV): median (0.3, 0.35, 0.5)" in p.explain()

    # Weight 0 and 1 per check (pixels across a check's edge average the two): the pixels of
    # weight 0 keep Combined to the bit, those of weight 1 change.
    mask = np.rint(passes["Material Index"]) == measured.index
    w = weight_map(measured, passes, mask)
    inner = interior(mask)
    assert {0.0, 1.0} <= set(np.unique(w[inner]).tolist())
    out = core_apply.apply(passes, desc, "burley")
    sss = out["SSSLab.burley.SSS"]
    assert not np.any(sss[inner & (w == 0.0)])
    assert np.any(sss[inner & (w == 1.0)])


def test_typed_in_inputs_render_no_input_aov(addon, sss_quads, tmp_path):
    """Nothing linked (Wax's Weight comes from a Value node, read exactly): no input AOV is
    rendered, the materials read nothing per pixel."""
    assert all(not m.per_pixel for m in sss_materials(sss_quads))
    exr, _ = render_passes(sss_quads, str(tmp_path), techniques=["burley"], log=None)
    assert not set(read_passes(exr).names) & {a.name for a in INPUT_AOVS.values()}


def test_the_asset_sample_scene_is_read_per_pixel(addon, tmp_path):
    """``asset_head`` (a node-group skin with an image-textured Base Color behind a glossy coat, a
    noise-textured marble): both Base Colors come back from the render within the range their
    texture spans (the sockets hold Blender's 0.8 grey, outside the skin's blue range), and the
    plan says where each was read."""
    from sss_lab.blender.samples import load_sample_scenes

    path = tmp_path / "asset_head.blend"
    load_sample_scenes().build("asset_head", str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    image = bpy.data.images["Skin Albedo"]
    texels = np.array(image.pixels[:], np.float32).reshape(-1, 4)[:, :3]
    exr, _ = render_passes(scene, str(tmp_path / "out"), techniques=["burley"], samples=4, resolution="48x48", log=None)
    passes, desc = read_passes(exr), load_scene(exr)
    p = plan(passes, desc, "burley")
    read = {mp.material.name: mp.material for mp in p.materials}
    assert read["Skin"].measured and read["Marble"].measured
    skin = np.array(read["Skin"].base_color)
    assert np.all(skin >= texels.min(axis=0) - 1e-3) and np.all(skin <= texels.max(axis=0) + 1e-3), skin
    assert skin[2] < 0.8 - 0.1  # not the socket's grey
    marble = np.array(read["Marble"].base_color)
    dark, light = np.array((0.62, 0.58, 0.55)), np.array((0.9, 0.87, 0.84))  # the colour ramp's ends
    assert np.all(marble >= dark - 1e-3) and np.all(marble <= light + 1e-3), marble
    text = p.explain()
    assert "Skin" in text and "reached through Mix Shader" in text and "'SSSLab Base Color' AOV): median" in text
