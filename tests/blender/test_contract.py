"""The contract between a technique's spec and the Blender layers (``tests/core/test_contract.py``
holds the core ones): every registered technique has its property group with one property per
parameter (default, range and choices from the spec), the panel draws a row for each, Apply
passes them on as keywords of its function, and the compositor has a builder for it or says why
not. ``docs/adding-a-technique.md`` is the recipe these checks follow."""

from types import SimpleNamespace

import bpy
import pytest

from sss_lab.core.scene.passes import PASSES, THICKNESS
from sss_lab.core.techniques.registry import TECHNIQUES
from sss_lab.nodes import setup as chain

IDS = list(TECHNIQUES)


class _Layout(SimpleNamespace):
    """Records the properties a panel draws (and their owner)."""

    def __init__(self, drawn):
        super().__init__(drawn=drawn, use_property_split=False, use_property_decorate=False)

    def prop(self, data, name, **_):
        assert name in data.bl_rna.properties, name
        self.drawn.append((data, name))

    def column(self, **_):
        return self

    row = box = column

    def operator(self, *_, **__):
        return SimpleNamespace()

    def label(self, **_):
        pass

    def separator(self, **_):
        pass

    operator_menu_enum = operator


@pytest.mark.parametrize("name", IDS)
def test_each_technique_has_its_properties(addon, name):
    spec = TECHNIQUES[name]
    group = getattr(bpy.context.scene.sss_lab, name)
    for p in spec.params:
        prop = group.bl_rna.properties[p.name]
        assert prop.name == p.label and prop.description == p.description
        if p.choices:
            assert [item.identifier for item in prop.enum_items] == [str(v) for v in p.values]
            assert prop.default == str(p.default)
        else:
            assert prop.default == pytest.approx(p.default)
            if p.min is not None:
                assert prop.hard_min == pytest.approx(p.min)
    # Apply passes the panel's values on as keywords of the function, at their defaults here.
    # (Blender stores float properties as float32.)
    options = bpy.context.scene.sss_lab.technique_options(name)
    assert set(options) == set(spec.defaults)
    for key, value in spec.defaults.items():
        assert options[key] == (pytest.approx(value, rel=1e-7) if isinstance(value, float) else value)


@pytest.mark.parametrize("name", IDS)
def test_the_panel_draws_a_row_per_parameter(addon, name):
    from sss_lab.addon.panels import draw_technique_parameters

    settings = bpy.context.scene.sss_lab
    settings.technique = name
    drawn = []
    draw_technique_parameters(_Layout(drawn), settings)
    group = getattr(settings, name)
    rows = [n for data, n in drawn if data == group]
    assert rows == list(TECHNIQUES[name].param_names)
    assert ("albedo_mode" in [n for _, n in drawn]) == TECHNIQUES[name].scatters


@pytest.mark.parametrize("name", IDS)
def test_a_compositor_builder_or_the_reason_for_none(name):
    spec = TECHNIQUES[name]
    if name in chain.NO_BUILDER:
        assert name not in chain.BUILDERS and len(chain.NO_BUILDER[name]) > 20
        with pytest.raises(ValueError, match="has no compositor group: " + chain.NO_BUILDER[name][:20]):
            chain.builder(name)
        return
    builder = chain.builder(name)
    for pass_name in builder.passes:
        assert pass_name == THICKNESS or pass_name in PASSES
        assert pass_name in spec.passes  # the groups read nothing the technique does not
    assert chain.group_name(name).startswith(f"SSS Lab {spec.label}")
