"""Blender's conventions for SSS Lab's operators: one-line tooltips, undo where data changes, the
technique as a dropdown."""

import bpy

from sss_lab.core.techniques import TECHNIQUES

#: Operators that change no Blender data (they read the scene, or write files only): no undo step.
NO_DATA_CHANGE = {"scan_scene", "compare"}


def _operators(addon):
    import sss_lab

    classes = []
    for module in sss_lab.addon._modules():
        classes += [c for c in module.classes if issubclass(c, bpy.types.Operator)]
    return {c.bl_idname.partition(".")[2]: c for c in classes}


def test_every_operator_has_a_one_line_tooltip_and_undo_where_it_changes_data(addon):
    operators = _operators(addon)
    assert NO_DATA_CHANGE < set(operators) and len(operators) >= 7
    for name, cls in operators.items():
        tip = getattr(bpy.ops.sss_lab, name).get_rna_type().description
        assert tip and "\n" not in tip and len(tip) <= 120, (name, tip)
        assert ("UNDO" in cls.bl_options) == (name not in NO_DATA_CHANGE), (name, cls.bl_options)


def test_apply_and_set_up_take_the_technique_from_a_dropdown(addon):
    for name in ("apply", "setup_compositor"):
        prop = getattr(bpy.ops.sss_lab, name).get_rna_type().properties["technique"]
        assert prop.type == "ENUM" and prop.default == "PANEL", name
        assert [item.identifier for item in prop.enum_items] == ["PANEL", *TECHNIQUES], name
