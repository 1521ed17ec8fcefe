"""core/scene/exr.py against what bpy 5.2 really writes: a 64x48 Cycles render, 2 samples, multilayer
EXR with the passes the techniques use and a value AOV named Thickness; and Blender reading
back the layers SSS Lab adds."""

import bpy
import numpy as np
import pytest

from sss_lab.blender import compat
from sss_lab.core.scene.exr import read_layers, read_passes, write_layers

W, H = 64, 48


def _render_passes(path, color_depth="32"):
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 2
    scene.cycles.use_denoising = False
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100

    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    # Looking 0.32 rad below the horizon from z = 1 while the sphere's centre is 0.2 rad below:
    # the sphere sits in the upper part of the picture.
    cam.location = (0.0, -5.0, 1.0)
    cam.rotation_euler = (1.25, 0.0, 0.0)
    scene.camera = cam

    mesh = bpy.data.meshes.new("Sphere")
    import bmesh

    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=1.0)
    bm.to_mesh(mesh)
    bm.free()
    sphere = bpy.data.objects.new("Sphere", mesh)
    scene.collection.objects.link(sphere)
    sphere.pass_index = 3
    mat = bpy.data.materials.new("Skin")
    compat.ensure_node_tree(mat)
    mat.pass_index = 2
    tree = mat.node_tree
    aov = tree.nodes.new("ShaderNodeOutputAOV")
    aov.aov_name = "Thickness"
    value = tree.nodes.new("ShaderNodeValue")
    value.outputs[0].default_value = 0.25
    tree.links.new(value.outputs[0], aov.inputs["Value"])
    mesh.materials.append(mat)

    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)

    vl = scene.view_layers[0]
    for flag in (
        "use_pass_combined",
        "use_pass_z",
        "use_pass_normal",
        "use_pass_position",
        "use_pass_diffuse_direct",
        "use_pass_diffuse_indirect",
        "use_pass_diffuse_color",
        "use_pass_object_index",
        "use_pass_material_index",
    ):
        setattr(vl, flag, True)
    thickness = vl.aovs.add()
    thickness.name, thickness.type = "Thickness", "VALUE"

    compat.set_multilayer_exr(scene.render.image_settings, color_depth=color_depth)
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return path


@pytest.mark.slow
@pytest.mark.parametrize("color_depth", ["32", "16"])
def test_reads_a_real_blender_render(tmp_path, color_depth):
    path = _render_passes(tmp_path / "passes.exr", color_depth)
    contents = read_layers(path)
    assert (contents.parts > 1) == compat.exr_part_per_pass()  # 5.2: one part per pass; 4.5: one part
    p = read_passes(path)
    assert p.view_layer == "ViewLayer"
    for name, shape in (
        ("Combined", (H, W, 4)),
        ("Depth", (H, W)),
        ("Normal", (H, W, 3)),
        ("Position", (H, W, 3)),
        ("Diffuse Direct", (H, W, 3)),
        ("Diffuse Indirect", (H, W, 3)),
        ("Diffuse Color", (H, W, 3)),
        ("Object Index", (H, W)),
        ("Material Index", (H, W)),
        ("Thickness", (H, W)),
    ):
        assert p[name].shape == shape, name
        assert p[name].dtype == np.float32, name
    if color_depth == "16":
        assert "Diffuse Direct" in p.half and "Depth" not in p.half
    on_sphere = p["Material Index"] == 2
    assert on_sphere.any()
    np.testing.assert_array_equal(p["Object Index"][on_sphere], 3)
    # The AOV value node writes 0.25 (exact in float32). AOVs are averaged over the samples
    # while the index is the first sample's, so only pixels whose neighbours are all on the
    # sphere are fully covered.
    pad = np.pad(on_sphere, 1)
    interior = on_sphere & pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
    assert interior.sum() > 100
    np.testing.assert_array_equal(p["Thickness"][interior], 0.25)
    # Background: depth 1e10 and index 0 (docs/references.md §2).
    assert (p["Depth"][~on_sphere] == np.float32(1e10)).all()
    assert (p["Object Index"][~on_sphere] == 0).all()
    # Rows run top to bottom: the sphere is in the upper part of the picture.
    rows = np.nonzero(on_sphere.any(axis=1))[0]
    assert rows[0] == 0 and rows[-1] < H // 2 + 10
    # Normals are world-space unit vectors averaged over the 2 samples: on a flat-shaded 16 x 8
    # UV sphere two samples fall on facets at most about 32 degrees apart (a diagonal step of
    # 22.5 degrees each way), so the average has length >= cos(16 deg) = 0.96.
    lengths = np.linalg.norm(p["Normal"][interior], axis=-1)
    assert lengths.min() >= 0.96 and lengths.max() <= 1.0 + 1e-3  # 1e-3: float32 normals


@pytest.mark.slow
def test_blender_reads_the_layers_sss_lab_adds(tmp_path):
    path = _render_passes(tmp_path / "passes.exr")
    contents = read_layers(path)
    layers = dict(contents.layers)
    layers["SSSLab.burley.Image"] = np.full((H, W, 4), 1e6, np.float32)  # above the half range
    layers["SSSLab.burley.SSS"] = np.zeros((H, W, 3), np.float32)
    out = write_layers(tmp_path / "passes.sss.exr", layers, contents.header, channels=contents.channels)

    image = bpy.data.images.load(out)
    tree = bpy.data.node_groups.new("Read", "CompositorNodeTree")
    node = tree.nodes.new("CompositorNodeImage")
    node.image = image
    node.layer = "SSSLab.burley"
    assert {o.name for o in node.outputs if o.enabled} == {"Image", "SSS"}
    node.layer = "ViewLayer"
    outputs = {o.name for o in node.outputs if o.enabled}
    names = ("Combined", "Diffuse Direct", "Depth", "Thickness", "Material Index")
    assert {compat.exr_pass_name(n) for n in names} <= outputs
