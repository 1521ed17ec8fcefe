"""A technique that fails leaves the comparison to the others: its run and its row of the fidelity
table become notes with the error (no render: synthetic passes, techniques of a registry of
their own)."""

import numpy as np
import pytest

from sss_lab.blender import compare as compare_mod
from sss_lab.core.scene.exr import Passes
from sss_lab.core.study.report_schema import Report
from sss_lab.core.study.synthetic import sphere_scene
from sss_lab.core.techniques.registry import Registry
from sss_lab.core.techniques.spec import Technique

PASSES = ("Combined", "Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Depth", "Material Index")


def halve(*, diffuse, albedo, mask):
    out = (albedo * diffuse).astype(np.float32)
    out[mask] *= np.float32(0.5)
    return out


def wants_more(*, diffuse, albedo, mask, light_probe):
    """Takes an input nobody offers: calling it raises TypeError."""
    raise AssertionError("never called")


def divides(*, diffuse, albedo, mask):
    """Overflows its arithmetic: raises ZeroDivisionError, an ArithmeticError."""
    return diffuse * (len(mask) // 0)


def _spec(name, function):
    return Technique(
        name=name,
        label=name.title(),
        description="a test stand-in",
        citation="tests/blender/test_compare_failures.py",
        function=function,
        scatters=True,
        adds_light=False,
        passes=PASSES,
    )


REGISTRY = Registry([_spec("halve", halve), _spec("wants_more", wants_more), _spec("divides", divides)])


@pytest.fixture(scope="module")
def scene():
    arrays, desc = sphere_scene(24, 16)
    return Passes(arrays), desc


def test_a_failing_technique_is_a_note_and_the_others_run(scene):
    passes, desc = scene
    notes, lines = [], []
    runs = {
        name: compare_mod.technique_run(passes, desc, REGISTRY[name], {}, (passes, desc), notes, lines.append)
        for name in REGISTRY
    }
    assert runs["wants_more"] is None and runs["divides"] is None
    good = runs["halve"]
    assert good.label == "Halve" and good.image.shape == passes["Combined"].shape and good.apply_s >= 0
    assert good.image_high is not None
    assert notes == [
        "Wants_More did not run: TypeError: wants_more() missing 1 required keyword-only argument: 'light_probe'",
        "Divides did not run: ZeroDivisionError: integer division or modulo by zero",
    ]
    assert any("not run (TypeError" in line for line in lines)

    fidelity_notes = []
    table = compare_mod._fidelity(desc, tuple(REGISTRY.values()), fidelity_notes)
    assert list(table["rows"]) == ["Halve", "Burley profile (analytic)"]
    assert [n.split(":")[:2] for n in fidelity_notes] == [
        ["fidelity table", " Wants_More not measured"],
        ["fidelity table", " Divides not measured"],
    ]
    # The notes are what the report's schema reads: an incomplete report that says why.
    report = Report.from_dict({"entries": [], "notes": notes + fidelity_notes, "complete": False, "fidelity": table})
    assert not report.complete and len(report.notes) == 4


def test_every_score_is_also_measured_per_material(scene):
    """With two subsurface materials each row carries its score on each one alone, beside the
    whole-image figure, and the report shows them; one material has no such breakdown."""
    from sss_lab.core.study.metrics import compare_images

    passes, desc = scene
    masks = compare_mod.material_masks(passes, desc)
    assert len(masks) == 2 and not any((a & b).any() for a, b in [tuple(masks.values())])
    ref = np.array(passes["Combined"], dtype=np.float32)
    image = ref.copy()
    first, second = masks
    image[masks[first]] *= np.float32(1.2)  # wrong on the first material only
    settings = compare_mod.CompareSettings(techniques=("burley",), box=1)
    rows = compare_mod._Rows(ref, masks[first] | masks[second], settings, lambda _line: None, materials=masks)
    rows.add("off on one", "technique", image, 1.0)
    by = rows.entries[0]["by_material"]
    assert by[second]["rel_rmse"] == 0.0 and by[first]["rel_rmse"] > 0.1
    assert by[first] == compare_images(image, ref, masks[first], box=1)
    assert (
        Report.from_dict({"entries": rows.entries, "pareto": [], "complete": True, "notes": []})
        .entries[0]
        .extra["by_material"]
        == by
    )
    one = compare_mod._Rows(ref, masks[first], settings, lambda _line: None, materials={first: masks[first]})
    one.add("off on one", "technique", image, 1.0)
    assert "by_material" not in one.entries[0]


def test_a_scene_whose_subsurface_materials_are_off_screen_is_named_not_scored(scene):
    """A camera turned away from every subsurface material: no pixel to score, so a clear error
    naming the materials instead of a report of NaN."""
    from sss_lab.core.base.errors import InputError

    passes, desc = scene
    away = dict(passes.arrays) if hasattr(passes, "arrays") else {k: passes[k] for k in passes.names}
    away["Material Index"] = np.zeros_like(passes["Material Index"])
    ref = passes["Combined"]
    with pytest.raises(InputError, match=r"no pixel of a subsurface material \('Skin', 'Wax'\) is on screen"):
        compare_mod._scattering_mask(Passes(away), desc, ref)
    assert compare_mod._scattering_mask(passes, desc, ref).any()
