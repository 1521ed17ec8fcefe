"""The version seam (blender/compat.py) on the Blender this suite runs with (5.2 or 4.5 LTS).

The same tests run on both versions (`make test` runs the suite once per version); where the
versions differ, each test states what the running version must do.
"""

from types import SimpleNamespace

import bpy
import pytest

from sss_lab.blender import compat
from sss_lab.blender.describe import material_sss
from sss_lab.core.scene.scene import SUBSURFACE_METHODS

IS_45 = bpy.app.version < (5, 0, 0)


def _principled(name="M"):
    mat = bpy.data.materials.new(name)
    compat.ensure_node_tree(mat)
    return mat, mat.node_tree.nodes["Principled BSDF"]


def test_the_running_blender_is_one_the_extension_declares():
    assert bpy.app.version[:2] in ((4, 5), (5, 2))
    assert compat.is_supported()
    with open(__file__.rsplit("/tests/", 1)[0] + "/blender_manifest.toml", encoding="utf-8") as f:
        manifest = f.read()
    assert 'blender_version_min = "4.5.0"' in manifest
    assert compat.MIN_VERSION == (4, 5, 0)


def test_subsurface_methods_round_trip_through_the_scene_description_names():
    mat, bsdf = _principled()
    methods = compat.subsurface_methods()
    assert set(methods) <= set(SUBSURFACE_METHODS)
    for method in methods:
        bsdf.subsurface_method = compat.subsurface_method_item(method)
        assert compat.subsurface_method(bsdf) == method
        bsdf.inputs["Subsurface Weight"].default_value = 1.0
        assert material_sss(mat, 1).method == method  # what the scene description records
    if IS_45:
        # 4.5's Random Walk is 5.2's Random Walk (Legacy): 5.2 converts it so on loading.
        assert methods == ("BURLEY", "RANDOM_WALK_LEGACY", "RANDOM_WALK_SKIN")
        assert compat.subsurface_method_item("RANDOM_WALK_LEGACY") == "RANDOM_WALK"
        assert compat.random_walk_method() == "RANDOM_WALK_LEGACY"
        with pytest.raises(ValueError, match=r"Blender 4\.5.*has no such method.*RANDOM_WALK_LEGACY"):
            compat.subsurface_method_item("RANDOM_WALK")
    else:
        assert methods == SUBSURFACE_METHODS
        assert compat.random_walk_method() == "RANDOM_WALK"


def test_thin_wall_is_set_where_it_exists_and_refused_where_it_cannot_be():
    _, bsdf = _principled()
    compat.set_thin_wall(bsdf, False)
    if "Thin Wall" in bsdf.inputs:
        assert bsdf.inputs["Thin Wall"].default_value is False
        compat.set_thin_wall(bsdf, True)
        assert bsdf.inputs["Thin Wall"].default_value is True
    else:
        assert IS_45
        with pytest.raises(RuntimeError, match="no Thin Wall input"):
            compat.set_thin_wall(bsdf, True)


def test_multires_bake_switch_and_eevee_name_exist_in_this_version():
    scene = bpy.context.scene
    owner, attr = compat.multires_bake_switch(scene)
    setattr(owner, attr, True)
    assert getattr(owner, attr) is True
    setattr(owner, attr, False)
    scene.render.engine = compat.eevee_engine()
    assert scene.render.engine == compat.eevee_engine()


def test_compositor_groups_are_available_or_the_set_up_says_what_this_blender_lacks(addon, sss_quads):
    from sss_lab.addon.panels import SSS_LAB_PT_compositor
    from sss_lab.operators.compositing import setup_compositor

    scene = sss_quads
    missing = compat.compositor_groups_missing()
    drawn, labels = [], []

    class Layout(SimpleNamespace):
        def operator(self, idname, **_):
            drawn.append(idname)

        def label(self, text="", **_):
            labels.append(text)

        def __getattr__(self, name):  # prop, column, row, box, separator...: accept and ignore
            return lambda *a, **k: self

    SSS_LAB_PT_compositor.draw(SimpleNamespace(layout=Layout()), bpy.context)
    assert "sss_lab.setup_compositor" in drawn  # greyed out by its poll where it cannot run
    if not IS_45:
        assert missing is None
        assert bpy.ops.sss_lab.setup_compositor.poll()
        assert not [t for t in labels if "Convolve" in t]
        return
    # 4.5: the reason names what is missing and what to use instead, and nothing is changed.
    assert "no compositor Convolve node" in missing and "Menu sockets" in missing and "Apply" in missing
    layer = scene.view_layers[0]
    before = (scene.node_tree, scene.use_nodes, layer.use_pass_diffuse_direct, bpy.data.materials["Skin"].pass_index)
    with pytest.raises(compat.MissingFeature, match="no compositor Convolve node"):
        setup_compositor(scene, "burley")
    assert not bpy.ops.sss_lab.setup_compositor.poll()
    with pytest.raises(RuntimeError, match="poll"):
        bpy.ops.sss_lab.setup_compositor(technique="burley")
    after = (scene.node_tree, scene.use_nodes, layer.use_pass_diffuse_direct, bpy.data.materials["Skin"].pass_index)
    assert after == before
    # The panel says plainly why, under the greyed button.
    assert any("no Convolve node" in t for t in labels) and any("Apply" in t for t in labels)


def test_compare_calibrates_only_the_methods_this_blender_renders():
    from sss_lab.blender.compare import CompareSettings

    for method in compat.subsurface_methods():
        CompareSettings(calibrate_methods=(method,)).validate()
    if IS_45:
        with pytest.raises(ValueError, match=r"Blender 4\.5.* has no subsurface method 'RANDOM_WALK'"):
            CompareSettings(calibrate_methods=("RANDOM_WALK",)).validate()
