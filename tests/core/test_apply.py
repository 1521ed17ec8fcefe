"""core/pipeline/plan.py and core/pipeline/apply.py: planning, compositing and the guards, on the analytic
plane-and-spheres scene
of core/study/synthetic.py (a plain material, index 1, and two scattering ones, indices 2 and 3).

Compositing is checked with stand-in techniques whose output is known in closed form, so
the expected images follow from the compositing formulas alone; the real techniques are run
too, for the properties that hold whatever they compute (untouched pixels, finite output).
"""

import dataclasses
import inspect
import math

import numpy as np
import pytest

from sss_lab.core.pipeline import plan as plan_mod
from sss_lab.core.pipeline.apply import apply
from sss_lab.core.pipeline.plan import plan, required_passes
from sss_lab.core.scene.exr import MissingPassError, Passes
from sss_lab.core.scene.scene import MaterialSSS
from sss_lab.core.study.synthetic import DEFAULT_MATERIALS, sphere_scene
from sss_lab.core.techniques.params import ENERGY_PARAM
from sss_lab.core.techniques.registry import TECHNIQUES


@pytest.fixture
def scene_passes():
    arrays, scene = sphere_scene()
    return Passes(arrays), scene, arrays


class Recorder:
    """A stand-in technique: records its calls and returns ``factor`` x albedo x diffuse on the
    mask and albedo x diffuse elsewhere (the contract of a technique that scatters), or for one
    that only adds light (STA) a constant ``added`` light on the mask."""

    def __init__(self, spec, factor=2.0, added=(0.25, 0.5, 1.0)):
        self.spec = spec
        self.factor = factor
        self.added = np.asarray(added, dtype=np.float32)
        self.calls = []

    def __call__(self, **kw):
        self.calls.append(kw)
        mask = kw["mask"]
        if not self.spec.scatters:
            out = np.zeros(kw["albedo"].shape, np.float32)
            out[mask] = self.added
            return out
        base = kw["albedo"] * kw["diffuse"]
        out = base.copy()
        out[mask] *= self.factor
        return out


class StubMapping:
    """Parameters as core.pipeline.mapping would give them; Burley's d is the Christensen-Burley method's
    radius / (4 pi) (docs/references.md §2)."""

    @staticmethod
    def burley_d(material, *, mapping=None):
        return tuple(r / (4 * math.pi) for r in material.radius)

    @staticmethod
    def technique_params(material, technique, *, mapping=None):
        """Fixed values, of the keywords the technique takes."""
        values = {"d_su": StubMapping.burley_d(material), "n_samples": 32, "thickness_distance_su": 1.0}
        values.update(distortion=0.1, power=2.0, scale=1.0, ambient=0.0)
        return {k: v for k, v in values.items() if k in technique.keywords}


@pytest.fixture
def stub(monkeypatch):
    """Replace the techniques and the parameter mapping with stand-ins; returns the recorders."""
    recorders = {name: Recorder(spec) for name, spec in TECHNIQUES.items()}

    def stand_in(spec):
        # The technique's own signature, so that apply's signature checks see what it takes and a
        # call without a required keyword, or with one it does not take, fails as it would; without
        # the energy stage (core/optics/energy.py), which the stand-in does not model.
        signature = inspect.signature(spec.function)
        signature = signature.replace(parameters=[p for n, p in signature.parameters.items() if n != ENERGY_PARAM.name])

        def function(**kw):
            signature.bind(**kw)
            return recorders[spec.name](**kw)

        function.__signature__ = signature
        return function

    # The registered specs with the stand-in functions.
    specs = {
        name: dataclasses.replace(
            spec, function=stand_in(spec), params=tuple(p for p in spec.params if p.name != ENERGY_PARAM.name)
        )
        for name, spec in TECHNIQUES.items()
    }
    monkeypatch.setattr(plan_mod, "get_spec", lambda t: specs[TECHNIQUES.get_spec(t).name])
    monkeypatch.setattr(plan_mod, "_mapping", lambda: StubMapping)
    return recorders


def test_required_passes_are_the_single_source():
    assert {"Diffuse Color", "Normal", "Position", "Material Index", "Thickness"} <= set(required_passes("sta"))
    for t in ("ssss", "burley"):
        assert {"Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Depth", "Material Index"} <= set(
            required_passes(t)
        )
    assert "Object Index" in required_passes("burley")
    assert "Translucency" in required_passes("sta", "Translucency")
    assert "Thickness" not in required_passes("sta", "Translucency")
    with pytest.raises(ValueError, match="unknown technique 'foo'.*sta, ssss, burley"):
        required_passes("foo")


def test_plan_lists_each_material_with_its_reason(stub, scene_passes):
    passes, scene, arrays = scene_passes
    p = plan(passes, scene, "burley")
    by_name = {m.material.name: m for m in p.materials}
    assert not by_name["Plaster"].applied and "Subsurface Weight is 0" in by_name["Plaster"].skip
    for name, index in (("Skin", 2), ("Wax", 3)):
        mp = by_name[name]
        assert mp.applied, mp.skip
        assert mp.pixels == int((arrays["Material Index"] == index).sum())
        z = arrays["Depth"][arrays["Material Index"] == index]
        assert mp.median_depth == pytest.approx(float(np.median(z)), rel=1e-6)
        # Kernel radius: Burley truncated at 16 d (docs/references.md §1), d = radius / 4 pi
        # from the stand-in mapping, times focal length in pixels over depth (docs/references.md §1).
        d = np.array(mp.material.radius) / (4 * math.pi)
        focal = 35.0 / 36.0 * 48  # lens 35 mm over a 36 mm sensor across 48 pixels
        np.testing.assert_allclose(mp.kernel_px, 16 * d * focal / np.median(z), rtol=1e-5)  # float32 depth
        assert mp.samples == 32
    text = p.explain()
    assert "Burley (burley)" in text and "48x32" in text
    assert "'Plaster'" in text and "Subsurface Weight is 0" in text
    assert "'Skin'" in text and "'Wax'" in text and "pixels at the median depth" in text
    assert "samples per pixel: 32" in text
    assert "2 of 3 materials computed" in text


def test_plan_skips_materials_below_a_pixel_or_off_screen(stub, scene_passes):
    passes, scene, _ = scene_passes
    tiny = dataclasses.replace(DEFAULT_MATERIALS[1], subsurface_scale=1e-6)
    away = MaterialSSS(index=9, name="Jade", subsurface_weight=1.0)
    scene = dataclasses.replace(scene, materials=(DEFAULT_MATERIALS[0], tiny, DEFAULT_MATERIALS[2], away))
    p = plan(passes, scene, "burley")
    by_name = {m.material.name: m for m in p.materials}
    # 16 * 1e-6 / (4 pi) scene units at depth ~3 with a 47 px focal length: ~2e-5 px.
    assert "at most one pixel" in by_name["Skin"].skip
    assert "no pixel on screen has Material Index 9" in by_name["Jade"].skip
    assert [m.material.name for m in p.applied] == ["Wax"]
    assert "no pixel on screen" in p.explain()


def test_only_matching_pixels_change(stub, scene_passes):
    passes, scene, arrays = scene_passes
    out = apply(passes, scene, "burley")
    assert set(out) == {"SSSLab.burley.Image", "SSSLab.burley.SSS"}
    image, sss = out["SSSLab.burley.Image"], out["SSSLab.burley.SSS"]
    assert image.dtype == np.float32 and image.shape == arrays["Combined"].shape
    assert sss.shape == arrays["Diffuse Color"].shape
    calls = stub["burley"].calls
    assert len(calls) == 2  # one call per scattering material
    masks = [c["mask"] for c in calls]
    mi = arrays["Material Index"]
    np.testing.assert_array_equal(masks[0], mi == 2)
    np.testing.assert_array_equal(masks[1], mi == 3)
    # The stand-in doubles the diffuse light: image = Combined - A E + 2 A E = Combined + A E,
    # except in a channel whose kernel (16 d) is at most one pixel even at the material's
    # nearest depth, which stays as it is: here Skin's blue, 16 * 0.03 / (4 pi) su * 46.7 px /
    # 2.9 = 0.6 px.
    diffuse = arrays["Diffuse Color"] * (arrays["Diffuse Direct"] + arrays["Diffuse Indirect"])
    focal = 35.0 / 36.0 * 48
    for index in (2, 3):
        material = scene.material(index)
        nearest = arrays["Depth"][mi == index].min()
        for c, radius in enumerate(material.radius):
            if 16 * radius / (4 * math.pi) * focal / nearest <= 1.0:
                diffuse[mi == index, c] = 0.0
    assert (diffuse[mi == 2, 2] == 0).all() and (diffuse[mi == 2, 1] > 0).all()
    on = (mi == 2) | (mi == 3)
    np.testing.assert_allclose(image[on, :3], arrays["Combined"][on, :3] + diffuse[on], rtol=1e-6)  # float32 sums
    np.testing.assert_allclose(sss[on], diffuse[on], rtol=1e-6)
    # Everything else, and the alpha everywhere, is Combined bit for bit.
    np.testing.assert_array_equal(image[~on], arrays["Combined"][~on])
    np.testing.assert_array_equal(image[..., 3], arrays["Combined"][..., 3])
    assert (sss[~on] == 0).all()
    # Each material's parameters reach the technique.
    np.testing.assert_allclose(calls[1]["d_su"], np.array(DEFAULT_MATERIALS[2].radius) / (4 * math.pi))
    np.testing.assert_array_equal(calls[0]["object_id"], arrays["Object Index"])


def test_sta_adds_its_term_on_the_material_pixels(stub, scene_passes):
    passes, scene, arrays = scene_passes
    out = apply(passes, scene, "sta")
    image, sss = out["SSSLab.sta.Image"], out["SSSLab.sta.SSS"]
    mi = arrays["Material Index"]
    on = (mi == 2) | (mi == 3)
    added = np.array([0.25, 0.5, 1.0], np.float32)
    np.testing.assert_array_equal(image[on, :3], arrays["Combined"][on, :3] + added)
    np.testing.assert_array_equal(image[~on], arrays["Combined"][~on])
    np.testing.assert_array_equal(sss[on], np.broadcast_to(added, sss[on].shape))
    call = stub["sta"].calls[0]
    assert call["lights"] == scene.lights and call["thickness_convention"] == "translucency"
    np.testing.assert_array_equal(call["thickness"], arrays["Thickness"])


def test_pre_post_albedo_splits_the_albedo_around_the_scatter(stub, scene_passes):
    passes, scene, arrays = scene_passes
    apply(passes, scene, "ssss", albedo_mode="pre-post")
    call = stub["ssss"].calls[0]
    root = np.sqrt(arrays["Diffuse Color"])
    np.testing.assert_allclose(call["albedo"], root, rtol=1e-7)
    np.testing.assert_allclose(
        call["diffuse"], root * (arrays["Diffuse Direct"] + arrays["Diffuse Indirect"]), rtol=1e-6
    )
    # A scatter that changes nothing (factor 1) gives back Combined whatever the split:
    # sqrt(A) * sqrt(A) E = A E.
    stub["ssss"].factor = 1.0
    out = apply(passes, scene, "ssss", albedo_mode="pre-post")["SSSLab.ssss.Image"]
    np.testing.assert_allclose(out, arrays["Combined"], rtol=1e-6, atol=1e-6)  # float32 rounding of sqrt
    with pytest.raises(ValueError, match="albedo_mode.*post, pre-post"):
        plan(passes, scene, "ssss", albedo_mode="pre")


def test_no_scattering_material_gives_nothing(stub, scene_passes):
    passes, scene, _ = scene_passes
    plain = tuple(dataclasses.replace(m, subsurface_weight=0.0) for m in scene.materials)
    scene = dataclasses.replace(scene, materials=plain)
    for technique in TECHNIQUES:
        p = plan(passes, scene, technique)
        assert p.scattering == [] and p.applied == []
        assert "no material in the scene description scatters light" in p.explain()
        assert apply(passes, scene, technique) == {}
    assert all(not r.calls for r in stub.values())


def test_nan_and_inf_pixels_are_left_as_they_are(stub, scene_passes):
    _, scene, arrays = scene_passes
    arrays = {k: v.copy() for k, v in arrays.items()}
    mi = arrays["Material Index"]
    skin = np.argwhere(mi == 2)
    a, b, c = map(tuple, skin[[10, 40, 70]])
    arrays["Diffuse Direct"][a] = np.nan
    arrays["Combined"][b] = np.inf
    arrays["Depth"][c] = np.nan
    plaster = tuple(np.argwhere(mi == 1)[5])
    arrays["Combined"][plaster] = np.nan  # not a scattering pixel: copied as it is
    passes = Passes(arrays)
    for technique in ("burley", "ssss"):
        out = apply(passes, scene, technique)
        image, sss = out[f"SSSLab.{technique}.Image"], out[f"SSSLab.{technique}.SSS"]
        for pixel in (a, b, c, plaster):
            np.testing.assert_array_equal(image[pixel], arrays["Combined"][pixel])
            assert (sss[pixel] == 0).all()
        bad = np.zeros(mi.shape, bool)
        for pixel in (a, b, c, plaster):
            bad[pixel] = True
        assert np.isfinite(image[~bad]).all() and np.isfinite(sss).all()
        # What reaches the technique is finite (the guard replaced NaN/Inf by 0 there).
        call = stub[technique].calls[-1]
        assert np.isfinite(call["diffuse"]).all() and np.isfinite(call["albedo"]).all()
        assert not call["mask"][a] and not call["mask"][c]
    # The plan counts them (the NaN on the plain plane is not one of its pixels).
    p = plan(passes, scene, "burley")
    apply(passes, scene, "burley", prepared=p)
    assert p.nonfinite_pixels == 3
    assert "3 pixels with NaN/Inf inputs: left as they are" in p.explain()


@pytest.mark.parametrize(
    "damage, count, value",
    [
        ("the whole of Skin at 2.5", None, 2.5),  # between two indices: counts as 2 (round half to even)
        ("three pixels filtered to 1.25", 3, 1.25),  # a resampled or filtered pass: its edges
        ("a negative fraction", 1, -0.5),
        ("whole numbers, NaN and inf", 0, None),  # not fractions: NaN/Inf match no material, unsaid
    ],
)
def test_a_material_index_that_is_not_a_whole_number_is_said(stub, scene_passes, damage, count, value):
    """Blender writes whole pass indices: every plan counts the finite pixels of the Material Index
    pass that are not whole numbers and its explain says how many, as a warning naming the pass."""
    _, scene, arrays = scene_passes
    mi = arrays["Material Index"].copy()
    skin = mi == 2
    if damage.startswith("the whole"):
        mi[skin] = 2.5
        count = int(skin.sum())
    elif damage.startswith("three"):
        for y, x in np.argwhere(skin)[:3]:
            mi[y, x] = 1.25
    elif damage.startswith("a negative"):
        mi[0, 0] = -0.5
    else:
        mi[0, 0], mi[0, 1] = np.nan, np.inf
    passes = Passes({**arrays, "Material Index": mi})
    for technique in TECHNIQUES:
        p = plan(passes, scene, technique)
        assert (p.fractional_index_pixels, p.fractional_index_value) == (count, value)
        if count:
            line = f"warning: the Material Index pass has {count} pixels that are not whole numbers (such as {value:g})"
            assert line in p.explain() and p.index_warning in p.explain()
            assert f"({value:g} as {int(np.rint(value))})" in p.index_warning
        else:
            assert p.index_warning is None and "whole numbers" not in p.explain()
    if damage.startswith("the whole"):
        # 2.5 counts as 2 (np.rint rounds half to even): Skin keeps its pixels, and the warning says so.
        skin_plan = next(m for m in plan(passes, scene, "burley").materials if m.material.index == 2)
        assert skin_plan.pixels == count


def test_a_plan_brings_its_pixels_to_apply_only_on_the_passes_it_read(stub, scene_passes):
    """``apply(prepared=plan(...))`` takes the pixels the plan found, instead of reading the
    Material Index pass again, only when it is given that same pass; on other passes (here the two
    scattering materials' indices swapped) it finds them itself, as without a plan."""
    passes, scene, arrays = scene_passes
    mi = arrays["Material Index"]
    p = plan(passes, scene, "burley")
    ks = [m.material.index for m in p.applied]
    assert len(ks) == 2 and sorted(p.planned_masks(passes)) == sorted(ks)
    for k in ks:
        assert np.array_equal(p.planned_masks(passes)[k], mi == k)
    apply(passes, scene, "burley", prepared=p)
    for call, k in zip(stub["burley"].calls[-2:], ks, strict=True):
        assert np.array_equal(call["mask"], mi == k)
    a, b = ks
    swapped = dict(arrays)
    swapped["Material Index"] = np.where(mi == a, np.float32(b), np.where(mi == b, np.float32(a), mi))
    other = Passes(swapped)
    assert p.planned_masks(other) == {}
    apply(other, scene, "burley", prepared=p)
    for call, k in zip(stub["burley"].calls[-2:], ks, strict=True):
        assert np.array_equal(call["mask"], swapped["Material Index"] == k)


def test_half_float_passes_are_computed_in_float32(stub, scene_passes):
    _, scene, arrays = scene_passes
    halves = {k: v.astype(np.float16) for k, v in arrays.items() if k != "Depth"}
    halves["Depth"] = arrays["Depth"]  # 1e10 background does not fit in half
    halves["Combined"][0, 0, :3] = 60000.0  # near the top of the half range, on the plain plane
    out = apply(Passes(halves), scene, "burley")["SSSLab.burley.Image"]
    widened = {k: v.astype(np.float32) for k, v in halves.items()}
    expected = apply(Passes(widened), scene, "burley")["SSSLab.burley.Image"]
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, expected)
    # 60000 + a doubled diffuse term would overflow half (max 65504) on a scattering pixel;
    # in float32 it does not.
    halves["Combined"][tuple(np.argwhere(arrays["Material Index"] == 2)[0])][:3] = 65504.0
    out = apply(Passes(halves), scene, "burley")["SSSLab.burley.Image"]
    assert np.isfinite(out).all() and out.max() > 65504.0


def test_unknown_method_and_mismatched_inputs(stub, scene_passes):
    passes, scene, arrays = scene_passes
    with pytest.raises(ValueError, match="unknown technique 'blur'; expected one of: sta, ssss, burley"):
        plan(passes, scene, "blur")
    with pytest.raises(ValueError, match="unknown technique"):
        apply(passes, scene, "blur")
    small = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, width_px=64))
    with pytest.raises(ValueError, match="64x32 pixels but the passes are 48x32"):
        plan(passes, small, "burley")
    with pytest.raises(ValueError, match="option.*n_taps.*not taken by burley"):
        plan(passes, scene, "burley", n_taps=3)
    no_depth = Passes({k: v for k, v in arrays.items() if k != "Depth"})
    with pytest.raises(MissingPassError, match="'Depth'.*SSSS technique.*Passes > Data > Depth"):
        plan(no_depth, scene, "ssss")
    no_thickness = Passes({k: v for k, v in arrays.items() if k != "Thickness"})
    with pytest.raises(MissingPassError, match="'Thickness'.*STA.*Shader AOV"):
        apply(no_thickness, scene, "sta")
