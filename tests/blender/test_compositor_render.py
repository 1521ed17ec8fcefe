"""The compositor path without hand work (addon/compositor_render.py, operators/compositing.py).

Set Up Compositor leaves the materials' Subsurface Weight as it is; every render that runs SSS
Lab's node groups renders the subsurface materials as plain diffuse and puts the weights (and
the links that drive them) back; Render Passes and Compare are left alone; a set-up runs again
after the camera or a light moved, after a render, and after the weight was set to 0 by hand.

The scene is conftest's ``sss_quads`` (16 x 16 pixels, 4 samples, fixed seed): Cycles on the CPU
gives the same pixels for the same scene and seed, which the image comparisons rely on.
"""

import bpy
import numpy as np
import pytest

from sss_lab.addon import compositor_render
from sss_lab.blender import compat
from sss_lab.blender.reference_cache import cached_reference
from sss_lab.blender.stored import KEPT_WEIGHT
from sss_lab.core.scene import exr
from sss_lab.nodes import _graph
from sss_lab.nodes.setup import NODE_TAG, group_name

# Skipped where the groups cannot run (Blender 4.5; tests/blender/conftest.py).
pytestmark = pytest.mark.compositor_groups


def _scene():
    """The ``sss_quads`` scene with a user's grade node in the compositor."""
    scene = bpy.context.scene
    compat.set_compositor_device(scene, "CPU")
    tree = compat.compositor_tree(scene, create=True)
    result = compat.compositor_result_socket(tree)
    rl = tree.nodes.new("CompositorNodeRLayers")
    grade = tree.nodes.new("CompositorNodeBrightContrast")
    grade.name = "My Grade"
    tree.links.new(rl.outputs["Image"], grade.inputs[0])
    tree.links.new(grade.outputs[0], result)
    return scene, tree


BEFORE = {"Skin": (1.0, False), "Wax": (1.0, True)}
PLAIN = {"Skin": (0.0, False), "Wax": (0.0, False)}  # Wax: its link cut and its own value 0


@pytest.fixture
def seen_while_rendering(quad_weights):
    """The materials' weights as a render_pre handler sees them, render by render."""
    seen = []

    def probe(scene, *_):
        seen.append(quad_weights())

    bpy.app.handlers.render_pre.append(probe)
    yield seen
    bpy.app.handlers.render_pre.remove(probe)


def _render_passes(tmp_path, name):
    """Render the scene (compositing as set) and read back its view layer's passes."""
    scene = bpy.context.scene
    layer = scene.view_layers[0]
    layer.use_pass_diffuse_direct = layer.use_pass_diffuse_color = True
    bpy.ops.render.render()
    compat.set_multilayer_exr(scene.render.image_settings)
    path = str(tmp_path / f"{name}.exr")
    bpy.data.images["Render Result"].save_render(filepath=path, scene=scene)
    return exr.read_passes(path, layer.name)


def test_a_render_through_the_node_groups_sees_plain_diffuse_and_gets_the_weights_back(
    addon, quad_weights, sss_quads, tmp_path, seen_while_rendering
):
    scene, tree = _scene()
    assert bpy.ops.sss_lab.setup_compositor(technique="burley") == {"FINISHED"}
    assert quad_weights() == BEFORE  # the set-up leaves the materials as they are
    assert scene.render.use_lock_interface
    assert bpy.data.materials["Skin"][KEPT_WEIGHT] == 1.0

    through_groups = _render_passes(tmp_path, "groups")
    assert seen_while_rendering == [PLAIN]
    assert quad_weights() == BEFORE
    wax = bpy.data.materials["Wax"].node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"]
    assert wax.links[0].from_node.name == "Weight"  # the link is back

    # The same pixels as the scene rendered with the weights set to 0 by hand, without node groups...
    for name in ("Skin", "Wax"):
        nodes = bpy.data.materials[name].node_tree.nodes
        socket = nodes["Principled BSDF"].inputs["Subsurface Weight"]
        for link in list(socket.links):
            bpy.data.materials[name].node_tree.links.remove(link)
        socket.default_value = 0.0
    scene.render.use_compositing = False
    by_hand = _render_passes(tmp_path, "by_hand")
    np.testing.assert_array_equal(through_groups["Diffuse Direct"], by_hand["Diffuse Direct"])
    # ...and not those of the scene rendered with subsurface scattering (the check can fail).
    for name in ("Skin", "Wax"):
        bpy.data.materials[name].node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 1.0
    scattered = _render_passes(tmp_path, "scattered")
    assert not np.array_equal(through_groups["Diffuse Direct"], scattered["Diffuse Direct"])


def test_other_renders_are_left_alone(addon, quad_weights, sss_quads, tmp_path, seen_while_rendering):
    scene, tree = _scene()
    bpy.ops.render.render()  # no SSS Lab node in the compositor
    assert bpy.ops.sss_lab.setup_compositor(technique="ssss") == {"FINISHED"}
    scene.render.use_compositing = False  # the groups do not run
    bpy.ops.render.render()
    scene.render.use_compositing = True
    for node in tree.nodes:
        if NODE_TAG in node.keys():
            node.mute = True  # muted groups do not run either
    bpy.ops.render.render()
    for node in tree.nodes:
        node.mute = False
    # Compare's Cycles reference is Cycles' own image, with its subsurface scattering.
    cached_reference(scene, str(tmp_path), samples=1, seed=0, resolution=(8, 8), method=None, log=lambda _l: None)
    assert seen_while_rendering == [BEFORE] * 4
    assert scene.render.use_compositing and quad_weights() == BEFORE


def test_a_cancelled_render_and_a_disabled_add_on_put_the_weights_back(addon, quad_weights, sss_quads):
    scene, _ = _scene()
    assert bpy.ops.sss_lab.setup_compositor(technique="burley") == {"FINISHED"}
    registered = {name: fn for name, fn in compositor_render._HANDLERS}
    assert registered["render_cancel"] in bpy.app.handlers.render_cancel
    assert registered["render_init"] in bpy.app.handlers.render_init
    # Esc during a render: Blender calls render_init, then render_cancel.
    registered["render_init"](scene)
    assert quad_weights() == PLAIN
    registered["render_cancel"](scene)
    assert quad_weights() == BEFORE
    # The add-on disabled while a render runs.
    registered["render_init"](scene)
    addon.unregister()
    try:
        assert quad_weights() == BEFORE
        assert registered["render_init"] not in bpy.app.handlers.render_init
    finally:
        addon.register()


def _pixels_per_unit(tree, technique="burley"):
    return _graph.read_meta(tree.nodes[group_name(technique, "Skin")].node_tree)["pixels_per_unit"]


def test_set_up_runs_again_after_moving_the_camera_or_a_light_and_after_a_render(addon, quad_weights, sss_quads):
    scene, tree = _scene()
    assert bpy.ops.sss_lab.setup_compositor(technique="burley") == {"FINISHED"}
    far = _pixels_per_unit(tree)
    bpy.ops.render.render()
    scene.camera.location.y = -2.0  # half as far: twice the pixels per unit
    bpy.context.view_layer.update()
    assert bpy.ops.sss_lab.setup_compositor(technique="burley") == {"FINISHED"}
    assert _pixels_per_unit(tree) == pytest.approx(2 * far, rel=1e-6)
    # STA reads the light's direction into its group node: a moved light is picked up.
    for name in ("Skin", "Wax"):
        mat_tree = bpy.data.materials[name].node_tree
        aov = mat_tree.nodes.new("ShaderNodeOutputAOV")
        aov.aov_name = "Thickness"
        value = mat_tree.nodes.new("ShaderNodeValue")
        mat_tree.links.new(value.outputs[0], aov.inputs["Value"])
    assert bpy.ops.sss_lab.setup_compositor(technique="sta") == {"FINISHED"}
    sun = bpy.data.objects["Sun"]
    sun.rotation_euler = (0.0, 0.0, 0.0)  # now shines straight down (-Z)
    bpy.context.view_layer.update()
    assert bpy.ops.sss_lab.setup_compositor(technique="sta") == {"FINISHED"}
    node = tree.nodes["SSS Lab STA Sun"]
    assert tuple(node.inputs["light_direction"].default_value)[:3] == pytest.approx((0.0, 0.0, -1.0), abs=1e-6)
    assert quad_weights() == BEFORE


def test_set_up_finds_a_material_whose_weight_was_set_to_0_by_hand(addon, sss_quads):
    scene, tree = _scene()
    assert bpy.ops.sss_lab.setup_compositor(technique="burley") == {"FINISHED"}
    skin = bpy.data.materials["Skin"].node_tree.nodes["Principled BSDF"]
    skin.inputs["Subsurface Weight"].default_value = 0.0  # the old hand work
    assert bpy.ops.sss_lab.setup_compositor(technique="burley") == {"FINISHED"}
    assert group_name("burley", "Skin") in tree.nodes
    # A material never set up, at weight 0, is not scattering: said clearly when nothing is left.
    for name in ("Skin", "Wax"):
        mat = bpy.data.materials[name]
        del mat[KEPT_WEIGHT]
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        for link in list(bsdf.inputs["Subsurface Weight"].links):
            mat.node_tree.links.remove(link)
        bsdf.inputs["Subsurface Weight"].default_value = 0.0
    with pytest.raises(RuntimeError, match="keep the materials' Subsurface Weight"):
        bpy.ops.sss_lab.setup_compositor(technique="burley")
