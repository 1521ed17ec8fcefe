"""Blender's conventions for SSS Lab's operators: one-line tooltips, undo where data changes, the
technique as a dropdown."""

import bpy

from sss_lab.core.techniques.registry import TECHNIQUES

#: Operators that change no Blender data (they read the scene, or write files only): no undo step.
NO_DATA_CHANGE = {"scan_scene", "recommend", "compare", "export_profiles"}


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
    from sss_lab.nodes.setup import BUILDERS

    for name, offered in (("apply", list(TECHNIQUES)), ("setup_compositor", [t for t in TECHNIQUES if t in BUILDERS])):
        prop = getattr(bpy.ops.sss_lab, name).get_rna_type().properties["technique"]
        assert prop.type == "ENUM" and prop.default == "PANEL", name
        assert [item.identifier for item in prop.enum_items] == ["PANEL", *offered], name
    # Set Up Compositor offers only what it can build (the combined technique has no node groups).
    assert "combined" not in BUILDERS and "combined" in TECHNIQUES


#: The Render tab's SSS Lab panels, top to bottom: the workflow's order.
RENDER_TAB = ["SSS Lab", "Parameters", "Thickness Bake", "Render Passes", "Apply", "Compositor", "Compare with Cycles"]
#: Where each step's button is.
BUTTONS = {
    "sss_lab.bake_thickness": "Thickness Bake",
    "sss_lab.render_passes": "Render Passes",
    "sss_lab.apply": "Apply",
    "sss_lab.setup_compositor": "Compositor",
    "sss_lab.compare": "Compare with Cycles",
}


def test_render_tab_panels_follow_the_workflow_with_every_row_split(draw_panels):
    rows = draw_panels("render")
    shown = list(dict.fromkeys(panel for panel, *_ in rows))
    assert shown == RENDER_TAB
    buttons = [(panel, name) for panel, kind, name, _ in rows if kind == "operator"]
    for idname, panel in BUTTONS.items():
        assert [p for p, name in buttons if name == idname] == [panel], idname  # once, in its step
    props = [(panel, name) for panel, kind, name, split in rows if kind == "prop" and not split]
    assert props == []  # label left, value right, as Cycles' panels
    assert all(kind != "menu" for _, kind, *_ in rows)  # the material preset is in the Material tab
