"""core/pipeline/auto.py: the features, the choice, the composite and the learning of ``apply --methods auto``.

Expected values come from independent computations: a naive loop for the masked box average, the
combined technique's own transmission for the light from behind, ``core.pipeline.apply.apply`` per
technique for the composite, and coefficients drawn at random for the learning."""

import dataclasses
import math

import numpy as np
import pytest

from sss_lab.core.base.errors import InputError
from sss_lab.core.pipeline import apply as core_apply
from sss_lab.core.pipeline import auto
from sss_lab.core.pipeline.mapping import burley_d
from sss_lab.core.scene.exr import Passes
from sss_lab.core.scene.scene import Camera, MaterialSSS, SceneDescription
from sss_lab.core.study.metrics import box_downsample
from sss_lab.core.study.synthetic import sphere_scene

#: The Burley profile's mean distance in units of d: the first moment of (e^{-r/d} + e^{-r/3d}) / (4 d),
#: (d^2 + 9 d^2) / (4 d) = 2.5 d.
MEAN_DISTANCE_CHECK = (1.0 + 9.0) / 4.0

#: A model under which every technique is predicted by hand: no SSS keeps the diffusion and the
#: light from behind; SSSS and Burley remove most of the diffusion; STA the light from behind.
MODEL = auto.Model(
    {
        "none": (1.0, 1.0, 0.0),
        "sta": (1.0, 0.3, 0.0),
        "ssss": (0.2, 1.0, 0.0),
        "burley": (0.19, 1.0, 0.0),
        "combined": (0.19, 0.1, 0.0),
    },
    command="test",
)


def _scene(distance=0.5):
    arrays, scene = sphere_scene(64, 48)
    mats = tuple(dataclasses.replace(m, thickness_distance=distance) if m.scatters else m for m in scene.materials)
    return arrays, dataclasses.replace(scene, materials=mats)


def test_masked_box_average_matches_a_naive_loop():
    rng = np.random.default_rng(1)
    e = rng.random((13, 17))
    mask = rng.random((13, 17)) < 0.7
    h = 2
    got = auto._blurred(e, mask, h)
    for y in range(13):
        for x in range(17):
            ys, xs = slice(max(y - h, 0), y + h + 1), slice(max(x - h, 0), x + h + 1)
            m = mask[ys, xs]
            expected = e[ys, xs][m].mean() if m.any() else e[y, x]
            assert got[y, x] == pytest.approx(expected, rel=1e-12)


def _flat(n=32, light=None, d_su=0.01, ppu=100.0):
    """A flat material facing an orthographic camera, ``ppu`` pixels per scene unit."""
    camera = Camera(type="ORTHO", width_px=n, height_px=n, ortho_scale=n / ppu)
    e = np.ones((n, n, 3), np.float32) if light is None else light
    arrays = {
        "Combined": np.concatenate([0.5 * e, np.ones((n, n, 1), np.float32)], axis=2),
        "Diffuse Direct": e,
        "Diffuse Indirect": np.zeros((n, n, 3), np.float32),
        "Diffuse Color": np.full((n, n, 3), 0.5, np.float32),
        "Depth": np.full((n, n), 2.0, np.float32),
        "Material Index": np.ones((n, n), np.float32),
        "Object Index": np.ones((n, n), np.float32),
    }
    m = MaterialSSS(
        index=1,
        name="M",
        method="RANDOM_WALK",
        base_color=(0.5, 0.5, 0.5),
        subsurface_radius=(1, 1, 1),
        subsurface_scale=d_su,
    )
    return Passes(arrays), SceneDescription(camera=camera, lights=(), materials=(m,))


def test_diffusion_is_zero_on_flat_light_and_under_half_a_pixel():
    passes, scene = _flat()
    f = auto.features(passes, scene, scene.materials[0])
    assert f.diffusion == pytest.approx(0.0, abs=1e-9)  # spreading uniform light changes nothing
    edge = np.ones((32, 32, 3), np.float32)
    edge[:, 16:] = 0.0
    passes, scene = _flat(light=edge, d_su=0.001)  # d under 0.2 px: 2.5 d < 0.5 px
    f = auto.features(passes, scene, scene.materials[0])
    expected_px = burley_d(scene.materials[0])[0] * 100.0
    assert f.footprint_px[0] == pytest.approx(expected_px, rel=1e-5)
    assert MEAN_DISTANCE_CHECK * expected_px < 0.5
    assert f.diffusion == 0.0


def test_diffusion_grows_with_the_footprint_at_a_shadow_edge():
    edge = np.ones((32, 32, 3), np.float32)
    edge[:, 16:] = 0.0
    values = []
    for d in (0.01, 0.04, 0.1):
        passes, scene = _flat(light=edge, d_su=d)
        values.append(auto.features(passes, scene, scene.materials[0]).diffusion)
    assert 0 < values[0] < values[1] < values[2]
    # Independently, on the 2 x 2 blocks (the edge falls between blocks 7 and 8): a box of
    # half-width round(2.5 d / 2) blocks; with albedo 0.5 the change is 0.5 x (mean of the box -
    # own value), the same in every channel and row.
    passes, scene = _flat(light=edge, d_su=0.04)
    h = round(MEAN_DISTANCE_CHECK * burley_d(scene.materials[0])[0] * 100.0 / 2)
    assert h >= 2
    e = edge[0, :, 0].reshape(16, 2).mean(axis=1)
    blurred = np.array([e[max(x - h, 0) : x + h + 1].mean() for x in range(16)])
    change = 0.5 * (blurred - e)
    expected = math.sqrt(np.mean(change**2)) / np.mean(0.5 * e)
    assert values[1] == pytest.approx(expected, rel=1e-6)


def test_wide_diffusion_is_the_diffusion_weighted_by_the_footprint_against_wide_px():
    edge = np.ones((64, 64, 3), np.float32)
    edge[:, 32:] = 0.0
    for d, ppu in ((0.04, 100.0), (0.04, 2000.0)):
        passes, scene = _flat(n=64, light=edge, d_su=d, ppu=ppu)
        f = auto.features(passes, scene, scene.materials[0])
        widest = max(burley_d(scene.materials[0])) * ppu
        assert f.diffusion > 0
        assert f.wide == pytest.approx(f.diffusion * min(1.0, widest / auto.WIDE_PX), rel=1e-6)
    assert f.wide == f.diffusion  # d of 80 px or more: all of it is wide
    # The model reads it with the fourth coefficient.
    model = auto.Model({"none": (1.0, 1.0, 0.0), "ssss": (0.2, 1.0, 0.0, 0.3)})
    g = auto.Features(name="m", index=1, pixels=1, diffusion=0.2, wide=0.1)
    assert model.predict("ssss", g) == pytest.approx(math.sqrt(0.2 * 0.04 + 0.3 * 0.01))
    assert model.predict("none", g) == pytest.approx(0.2)


def test_light_from_behind_is_the_combined_techniques_transmission():
    arrays, scene = _scene()
    passes = Passes(arrays)
    wax = scene.materials[2]
    f = auto.features(passes, scene, wax)
    from sss_lab.core.optics.medium import medium_of
    from sss_lab.core.pipeline.mapping import mean_free_path
    from sss_lab.core.techniques.combined.technique import transmission

    mask = np.rint(arrays["Material Index"]) == wax.index
    # On the 2 x 2 block means wholly inside the material (the whole image's blocks).
    keep = box_downsample(mask.astype(float), 2) >= 1

    def blocks(name):
        return box_downsample(arrays[name].astype(np.float64), 2)

    term = transmission(
        normal=blocks("Normal"),
        position=blocks("Position"),
        thickness=blocks("Thickness"),
        mask=keep,
        lights=scene.lights,
        d_su=tuple(mean_free_path(wax)),
        thickness_distance_su=0.5,
        medium=medium_of(wax),
        albedo=blocks("Diffuse Color"),
        camera=scene.camera,
    ).astype(np.float64)
    t = term[keep]
    # Relative to the mean of the image with that light (the reference's mean holds it too).
    base = (blocks("Combined")[..., :3] + term)[keep]
    assert f.back > 0
    assert f.back == pytest.approx(math.sqrt(np.mean(t**2)) / base.mean(), rel=1e-5)
    # Without the bake distance it cannot be measured, and says so.
    _, no_distance = _scene(distance=0.0)
    g = auto.features(passes, no_distance, no_distance.materials[2])
    assert g.back == 0.0 and any("bake distance" in n for n in g.notes)


def test_choose_takes_the_cheapest_within_the_margin():
    arrays, scene = _scene()
    passes = Passes(arrays)
    plan = auto.choose(passes, scene, model=MODEL, max_error=0.05)
    for c in plan.choices:
        ok = [k for k in c.candidates if k.excluded is None]
        best = min(k.predicted for k in ok)
        chosen = next(k for k in ok if k.name == c.chosen)
        assert chosen.predicted <= best * 1.05 + 1e-12
        # nothing cheaper (beyond the costs that count as equal) was within the margin
        assert all(k.cost * (1 + auto.COST_TOLERANCE) >= chosen.cost or k.predicted > best * 1.05 for k in ok)
    # Burley predicted at most 2.5 % better than SSSS (sqrt(0.19 / 0.2)) and costing about twice as
    # much; the light from behind counted alike for all three: SSSS, on both materials.
    even = auto.Model({"none": (1.0, 1.0, 0.0), "ssss": (0.2, 1.0, 0.0), "burley": (0.19, 1.0, 0.0)})
    picked = auto.choose(passes, scene, model=even, max_error=0.05)
    assert [c.chosen for c in picked.choices] == ["ssss", "ssss"], picked.explain()
    assert [c.chosen for c in auto.choose(passes, scene, model=even, max_error=0.0).choices] == ["burley", "burley"]
    # With no margin the best prediction wins.
    strict = auto.choose(passes, scene, model=MODEL, max_error=0.0)
    for c in strict.choices:
        ok = [k for k in c.candidates if k.excluded is None]
        assert c.chosen == min(ok, key=lambda k: k.predicted).name
    text = plan.explain()
    assert "material 'Skin'" in text and "diffusion D" in text and "light from behind B" in text
    assert "material 'Plaster': does not scatter light" in text


def test_a_huge_margin_leaves_everything_as_it_is():
    arrays, scene = _scene()
    plan = auto.choose(Passes(arrays), scene, model=MODEL, max_error=1e6)
    assert [c.chosen for c in plan.choices] == ["none", "none"]
    assert auto.apply_auto(Passes(arrays), scene, prepared=plan)["SSSLab.auto.SSS"].max() == 0.0


def test_missing_passes_exclude_a_technique_with_the_reason():
    arrays, scene = _scene()
    del arrays["Thickness"]
    plan = auto.choose(Passes(arrays), scene, model=MODEL)
    for c in plan.choices:
        excluded = {k.name: k.excluded for k in c.candidates if k.excluded}
        assert set(excluded) == {"sta", "combined"}
        assert all("Thickness" in why for why in excluded.values())
        assert c.chosen not in excluded


@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf, "5%"])
def test_bad_margin_is_one_clear_error(bad):
    arrays, scene = _scene()
    with pytest.raises(InputError, match="max_error"):
        auto.choose(Passes(arrays), scene, model=MODEL, max_error=bad)


def test_the_composite_is_each_materials_chosen_technique():
    arrays, scene = _scene()
    passes = Passes(arrays)
    # SSSS predicted better where the diffusion is small (Skin), Burley where it is large (Wax):
    # a model made up so that the two materials choose differently.
    # SSSS wins where 0.4 D^2 < 0.003, i.e. D < 0.087.
    model = auto.Model({"none": (1.0, 1.0, 0.0), "ssss": (0.5, 1.0, 0.0), "burley": (0.1, 1.0, 0.003)})
    plan = auto.choose(passes, scene, model=model, max_error=0.0, techniques=("ssss", "burley"))
    chosen = {c.features.name: c.chosen for c in plan.choices}
    assert chosen == {"Skin": "ssss", "Wax": "burley"}, plan.explain()
    out = auto.apply_auto(passes, scene, prepared=plan)
    index = np.rint(arrays["Material Index"])
    for name, t in chosen.items():
        ref = core_apply.apply(passes, scene, t)
        sel = index == next(m.index for m in scene.materials if m.name == name)
        np.testing.assert_array_equal(out["SSSLab.auto.SSS"][sel], ref[f"SSSLab.{t}.SSS"][sel])
        np.testing.assert_array_equal(out["SSSLab.auto.Image"][sel], ref[f"SSSLab.{t}.Image"][sel])
    rest = ~np.isin(index, [2, 3])
    np.testing.assert_array_equal(out["SSSLab.auto.Image"][rest], arrays["Combined"][rest])


def test_one_chosen_technique_gives_its_own_layers_as_the_composite_of_many_would():
    # apply_auto hands over the one chosen technique's layers: what the general composite
    # (Combined + the sum of the SSS terms) gives, Combined's pixels kept outside the materials.
    arrays, scene = _scene()
    for k, v in enumerate((np.nan, np.inf, -0.0, 1e30, 0.25)):  # off the materials: kept as they are
        arrays["Combined"][0, k, :3] = v
    passes = Passes(arrays)
    plan = auto.choose(passes, scene, model=MODEL, techniques=("burley",))
    assert set(plan.plans) == {"burley"} and len(plan.applied) == 2, plan.explain()
    out = auto.apply_auto(passes, scene, prepared=plan)
    ref = core_apply.apply(passes, scene, "burley")
    composite = np.array(arrays["Combined"], np.float32)
    composite[..., :3] += ref["SSSLab.burley.SSS"]
    np.testing.assert_array_equal(out["SSSLab.auto.Image"], composite)
    np.testing.assert_array_equal(out["SSSLab.auto.SSS"], ref["SSSLab.burley.SSS"])
    assert plan.nonfinite_pixels == ref_nonfinite(passes, scene)


def ref_nonfinite(passes, scene):
    p = core_apply.plan(passes, scene, "burley")
    core_apply.apply(passes, scene, "burley", prepared=p)
    return p.nonfinite_pixels


def test_train_recovers_the_coefficients_it_was_made_from():
    rng = np.random.default_rng(5)
    truth = {
        "none": (1.0, 1.0, 0.001, 0.0, 0.8),
        "ssss": (0.3, 1.0, 0.002, 0.2, 0.0),
        "combined": (0.25, 0.0, 0.004, 0.05, 0.1),
    }
    samples = []
    for i in range(16):
        d = float(rng.random())
        f = auto.Features(
            name=f"m{i}",
            index=1,
            pixels=100,
            diffusion=d,
            back=float(rng.random()),
            wide=d * float(rng.random()),
            view=0.2 * float(rng.random()),
        )
        errors = {
            t: math.sqrt(a * f.diffusion**2 + b * f.back**2 + c + w * f.wide**2 + v * f.view**2)
            for t, (a, b, c, w, v) in truth.items()
        }
        samples.append((f, errors))
    model = auto.train(samples)
    for t, coef in truth.items():
        np.testing.assert_allclose(model.coefficients[t], coef, atol=1e-9)
        # Predicting the samples it learnt from gives their errors back.
        f, errors = samples[3]
        assert model.predict(t, f) == pytest.approx(errors[t], rel=1e-9)


def test_model_validation_and_the_shipped_model():
    with pytest.raises(InputError, match="none"):
        auto.Model.from_dict({"coefficients": {"ssss": [1, 1, 0]}})
    with pytest.raises(InputError, match=">= 0"):
        auto.Model.from_dict({"coefficients": {"none": [1, -1, 0]}})
    shipped = auto.load_model()
    assert "none" in shipped.coefficients and shipped.trained_on and shipped.command


def test_the_shipped_model_never_saw_the_held_out_scenes():
    """The suite's held-out third stays out of every tuning decision, the shipped model's included."""
    from benchmarks.fidelity.scenes import held_out

    trained_on = auto.load_model().trained_on
    assert trained_on and not [name for name in trained_on if held_out(name)]


def test_fitted_energy_counts_against_techniques_without_the_fit():
    f = auto.Features(name="m", index=1, pixels=1, diffusion=0.1, energy=0.2, fitted=("burley",))
    assert MODEL.predict("burley", f) == pytest.approx(math.sqrt(0.19 * 0.01))
    assert MODEL.predict("none", f) == pytest.approx(math.sqrt(0.01 + 0.04))


def _cli(*args):
    from sss_lab.addon.cli import main

    return main(["apply", *map(str, args)])


def test_command_line_apply_auto_writes_the_auto_layers(tmp_path, capsys):
    from sss_lab.core.scene.exr import read_layers
    from sss_lab.core.study.synthetic import write_scene

    arrays, scene = _scene()
    path = write_scene(str(tmp_path / "passes.exr"), arrays, scene)
    assert _cli(path, "--methods", "auto", "--explain") == 0
    out = capsys.readouterr().out
    assert "diffusion D" in out and "=>" in out and not (tmp_path / "passes.sss.exr").exists()
    assert _cli(path, "--methods", "auto", "--max-error", "0.1") == 0
    out = capsys.readouterr().out
    assert "auto: material 'Skin':" in out and "Saved:" in out
    layers = read_layers(str(tmp_path / "passes.sss.exr")).layers
    assert "SSSLab.auto.Image" in layers and "SSSLab.auto.SSS" in layers
    expected = auto.apply_auto(Passes(arrays), scene, max_error=0.1)
    np.testing.assert_array_equal(layers["SSSLab.auto.SSS"], expected["SSSLab.auto.SSS"])


@pytest.mark.parametrize(
    "args, message",
    [
        (("--methods", "burley", "--max-error", "0.1"), "only --methods auto"),
        (("--methods", "auto,burley"), "stands alone: it cannot be combined with other methods"),
        (("--methods", "auto", "--max-error", "-1"), "--max-error: expected a number >= 0"),
    ],
)
def test_command_line_auto_bad_arguments_are_one_line(tmp_path, capsys, args, message):
    from sss_lab.core.study.synthetic import write_scene

    arrays, scene = _scene()
    path = write_scene(str(tmp_path / "passes.exr"), arrays, scene)
    assert _cli(path, *args) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) <= 2
    assert not (tmp_path / "passes.sss.exr").exists()


def test_keep_holds_an_earlier_choice_where_it_can_still_run():
    arrays, scene = _scene()
    even = auto.Model({"none": (1.0, 1.0, 0.0), "ssss": (0.2, 1.0, 0.0), "burley": (0.19, 1.0, 0.0)})
    alone = auto.choose(Passes(arrays), scene, model=even)
    assert alone.chosen == {"Skin": "ssss", "Wax": "ssss"}
    kept = auto.choose(Passes(arrays), scene, model=even, keep={"Skin": "burley", "Wax": "sta"})
    skin, wax = kept.choices
    assert skin.chosen == "burley" and "kept from the first frame" in skin.reason and "choose ssss" in skin.reason
    assert wax.chosen == "ssss"  # STA is not a candidate of this model: the frame's own choice stands


def test_command_line_auto_keeps_the_first_frames_choice_on_a_sequence(tmp_path, capsys):
    from sss_lab.core.scene.exr import read_layers
    from sss_lab.core.study.synthetic import write_scene

    arrays, scene = _scene()
    write_scene(str(tmp_path / "passes_0001.exr"), arrays, scene)
    flat = dict(arrays)
    flat["Diffuse Direct"] = np.full_like(arrays["Diffuse Direct"], 1.0)  # a frame lit evenly: nothing to spread
    write_scene(str(tmp_path / "passes_0002.exr"), flat, scene)
    assert _cli(str(tmp_path / "passes_####.exr"), "--methods", "auto") == 0
    first = auto.choose(Passes(arrays), scene)
    expected = auto.apply_auto(Passes(flat), scene, prepared=auto.choose(Passes(flat), scene, keep=first.chosen))
    got = read_layers(str(tmp_path / "passes_0002.sss.exr")).layers["SSSLab.auto.SSS"]
    np.testing.assert_array_equal(got, expected["SSSLab.auto.SSS"])


def test_costs_are_work_times_each_techniques_measured_rate():
    timings = [("ssss", 100.0, 2.0), ("ssss", 200.0, 2.0), ("ssss", 50.0, 1.5), ("burley", 100.0, 1.0)]
    f = auto.Features(name="m", index=1, pixels=1)
    model = auto.train([(f, {"none": 1.0, "ssss": 0.5})], timings=timings)
    assert model.seconds_per_work == {"ssss": pytest.approx(0.02), "burley": pytest.approx(0.01)}  # medians
    assert model.seconds("ssss", 1000.0) == pytest.approx(20.0)
    assert model.seconds("combined", 1000.0) == pytest.approx(20.0)  # unmeasured: the median rate (upper of two)
    assert model.seconds("none", 1000.0) == 0.0
    assert auto.Model.from_dict(model.to_dict()).seconds_per_work == model.seconds_per_work
    with pytest.raises(InputError, match="seconds_per_work"):
        auto.Model.from_dict({"coefficients": {"none": [1, 1, 0]}, "seconds_per_work": {"ssss": -1}})


def test_view_energy_is_what_the_techniques_energy_convention_changes():
    from sss_lab.core.optics.energy import entry_gain
    from sss_lab.core.techniques.combined.technique import view_cosine

    arrays, scene = _scene()
    passes = Passes(arrays)
    # Without the bake distance no light from behind is added: the measure divides by Combined's mean.
    walk = (m for m in scene.materials if m.scatters and m.method == "RANDOM_WALK")
    skin = dataclasses.replace(next(walk), thickness_distance=0.0)
    f = auto.features(passes, scene, skin)
    # Independently, on the 2 x 2 blocks wholly inside the material.
    mask = np.rint(arrays["Material Index"]) == skin.index
    keep = box_downsample(mask.astype(float), 2) >= 1

    def blocks(name):
        return box_downsample(arrays[name].astype(np.float64), 2)

    albedo = blocks("Diffuse Color")[..., :3]
    lit = (albedo * (blocks("Diffuse Direct")[..., :3] + blocks("Diffuse Indirect")[..., :3]))[keep]
    mu = view_cosine(blocks("Normal"), blocks("Position"), scene.camera)[keep]
    gain = entry_gain(skin.method, np.clip(albedo[keep], 0, 1), mu).astype(np.float64)
    gain *= lit.sum(axis=0) / (lit * gain).sum(axis=0)  # each channel's total kept
    assert f.view > 0
    base = blocks("Combined")[..., :3][keep].mean()
    assert f.view == pytest.approx(math.sqrt(np.mean((lit * (gain - 1)) ** 2)) / base, rel=1e-4)
    # A method without a table (Christensen-Burley: Lambert's energy) changes nothing.
    cb = dataclasses.replace(skin, method="BURLEY")
    assert auto.features(passes, scene, cb).view == 0.0


def _measured(scene, errors: dict, samples=(32,)):
    """``scene`` with every scattering material carrying a fit per technique of ``errors``, whose
    provenance says the fit measured that held-out error on a render of ``samples`` samples (one
    count per technique, cycled)."""
    fit = {
        t: {"gain": (1.0, 1.0, 1.0), "info": {"samples": samples[i % len(samples)], "heldout_after": e}}
        for i, (t, e) in enumerate(errors.items())
    }
    mats = tuple(dataclasses.replace(m, fit=fit) if m.scatters else m for m in scene.materials)
    return dataclasses.replace(scene, materials=mats)


def test_a_fits_measured_errors_decide_over_the_prediction():
    arrays, scene = _scene()
    passes = Passes(arrays)
    # Burley and Combined predicted alike; the fit measured Burley within 4 % of Combined.
    # Combined's light from behind costs it, per unit of work, three times Burley's rate.
    rates = {"ssss": 1.0, "burley": 1.0, "combined": 3.0}
    alike = {"none": (1.0, 1.0, 0.0), "sta": (1.0, 0.3, 0.0), "ssss": (0.2, 1.0, 0.0), "burley": (0.19, 1.0, 0.0)}
    model = auto.Model({**alike, "combined": (0.19, 1.0, 0.0)}, seconds_per_work=rates)
    measured = _measured(scene, {"burley": 0.100, "combined": 0.104})
    plan = auto.choose(passes, measured, model=model, max_error=0.05)
    for c in plan.choices:
        by = {k.name: k for k in c.candidates}
        assert c.chosen == "burley", plan.explain()
        # Burley is cheaper than Combined (fewer samples per pixel, no light added), so it is taken.
        assert by["burley"].cost < by["combined"].cost
        assert by["burley"].measured == 0.100 and by["combined"].measured == 0.104
        assert "measured" in c.reason
        for name in ("none", "sta", "ssss"):
            assert by[name].excluded and "not measured by the material's fit" in by[name].excluded
    assert "measured 0.1000 (its fit, held out)" in plan.explain()
    assert "the errors are predicted" not in plan.explain()
    # Combined measured 20 % better: beyond the margin, Combined.
    better = auto.choose(passes, _measured(scene, {"burley": 0.100, "combined": 0.080}), model=model, max_error=0.05)
    assert [c.chosen for c in better.choices] == ["combined", "combined"]
    # The same measurements with a margin of 25 %: Burley again (0.100 <= 1.25 x 0.080).
    wide = auto.choose(passes, _measured(scene, {"burley": 0.100, "combined": 0.080}), model=model, max_error=0.25)
    assert [c.chosen for c in wide.choices] == ["burley", "burley"]
    # Combined measured best, Burley within 4 % of it; MODEL predicts Combined 30 % better than
    # Burley on Wax (its light from behind), 1 % on Skin: the cheaper Burley, measured within the
    # margin, must be predicted within it too.
    measured = _measured(scene, {"burley": 0.104, "combined": 0.100})
    both = auto.choose(passes, measured, model=dataclasses.replace(MODEL, seconds_per_work=rates), max_error=0.05)
    predicted = {c.features.name: {k.name: k.predicted for k in c.candidates} for c in both.choices}
    assert predicted["Wax"]["burley"] > 1.05 * predicted["Wax"]["combined"]
    assert predicted["Skin"]["burley"] <= 1.05 * predicted["Skin"]["combined"]
    assert both.chosen == {"Skin": "burley", "Wax": "combined"}, both.explain()


def test_measurements_from_renders_of_different_noise_or_of_one_technique_are_not_compared():
    arrays, scene = _scene()
    passes = Passes(arrays)
    unfitted = auto.choose(passes, scene, model=MODEL, max_error=0.05)
    for errors, samples in (({"burley": 0.1, "combined": 0.5}, (32, 64)), ({"burley": 0.1}, (32,))):
        m = _measured(scene, errors, samples)
        assert all(auto.measured_errors(x) == {} for x in m.materials if x.scatters)
        plan = auto.choose(passes, m, model=MODEL, max_error=0.05)
        # The prediction decides, as without the measurements (the fit's gain is 1: no energy term).
        assert plan.chosen == unfitted.chosen
        assert all("predicted" in c.reason and "measured" not in c.reason for c in plan.choices)
        assert plan.explain().count("the errors are predicted (calibrate") == 2
    m = _measured(scene, {"burley": 0.1, "ssss": 0.2}, (32,))
    assert auto.measured_errors(next(x for x in m.materials if x.scatters)) == {"burley": 0.1, "ssss": 0.2}


def test_costs_within_the_tolerance_count_as_equal_and_the_lower_error_decides():
    arrays, scene = _scene()
    passes = Passes(arrays)
    skin = next(m for m in scene.materials if m.name == "Skin")
    pixels = auto.features(passes, scene, skin).pixels
    work = {t: auto._work(t, skin, pixels, len(scene.lights), None) for t in ("ssss", "burley")}
    coefficients = {"none": (1.0, 1.0, 0.0), "ssss": (0.2, 1.0, 0.0), "burley": (0.19, 1.0, 0.0)}

    def chosen(burley_over_ssss: float) -> str:
        # Rates such that Burley's estimated cost is burley_over_ssss times SSSS's on Skin.
        rates = {"ssss": 1.0 / work["ssss"], "burley": burley_over_ssss / work["burley"]}
        plan = auto.choose(passes, scene, model=auto.Model(coefficients, seconds_per_work=rates), max_error=0.05)
        return next(c for c in plan.choices if c.features.name == "Skin").chosen

    # Burley predicted lower (0.19 < 0.2 of D^2) and costing 5 % more: alike in cost, Burley.
    assert chosen(1.0 + 0.5 * auto.COST_TOLERANCE) == "burley"
    # Costing 20 % more (twice the tolerance): the cheaper SSSS, within the margin of 5 %.
    assert chosen(1.0 + 2.0 * auto.COST_TOLERANCE) == "ssss"


def test_the_features_block_means_are_the_error_measures_blocks():
    """With blocks of ``auto.BOX`` (the fidelity suite's size), ``auto._block_means`` takes the blocks
    ``core.study.metrics.box_downsample`` takes, cropped alike, every pixel read, and their means to
    float32's rounding: its float64 sum of four float32 values is exact, NumPy's float32 mean is
    within some 2^-24 times the block's size of it, and both are rounded to float32."""
    size = auto.BOX
    rng = np.random.default_rng(3)
    a = rng.uniform(0.0, 4.0, (37, 50, 3)).astype(np.float32)
    got = auto._block_means(a, size)
    expected = box_downsample(a, size)
    assert got.shape == expected.shape and got.dtype == np.float32
    np.testing.assert_allclose(got, expected, rtol=8 * 2.0**-24 * size, atol=0.0)
    mask = rng.uniform(size=(37, 50)) < 0.9
    assert np.array_equal(auto._block_inside(mask, size), box_downsample(mask.astype(np.float32), size) >= 1.0)


@pytest.mark.parametrize("size", [4, 6, 8, 12])
def test_larger_blocks_are_read_at_the_centres_of_their_quarters(size):
    """A block larger than ``auto.BOX`` (a window wider than ``GRID`` blocks) is represented by the
    pixel at the centre of each of its ``BOX`` x ``BOX`` parts: the features read BOX^2 values per
    block at any resolution. NaN and +-Inf read as 0, as ``core.pipeline.apply.clean`` reads them; pixels
    between the samples are not read at all. Tolerance: float32 rounding of a float64 mean of four
    float32 values (exact sum), i.e. half a unit in the last place."""
    rng = np.random.default_rng(5)
    a = rng.uniform(0.0, 4.0, (5 * size + 3, 7 * size + 1, 3)).astype(np.float32)
    part = size // auto.BOX
    offsets = [part // 2 + i * part for i in range(auto.BOX)]
    a[offsets[0], offsets[1], 0] = np.nan  # sampled: read as 0
    a[size + offsets[1], offsets[0], 2] = np.inf  # sampled: read as 0
    a[0, 0, 1] = np.nan  # between the samples (part >= 2 here): not read
    expected = np.zeros((5, 7, 3), np.float64)
    for by in range(5):
        for bx in range(7):
            for dy in offsets:
                for dx in offsets:
                    v = a[by * size + dy, bx * size + dx].astype(np.float64)
                    expected[by, bx] += np.where(np.isfinite(v), v, 0.0) / auto.BOX**2
    got = auto._block_means(a, size)
    assert got.shape == (5, 7, 3) and got.dtype == np.float32 and np.isfinite(got).all()
    np.testing.assert_allclose(got, expected, rtol=2.0**-24, atol=0.0)
    mask = np.ones(a.shape[:2], bool)
    mask[size + offsets[1], 2 * size + offsets[0]] = False  # a sample: its block is not inside
    mask[3 * size, 3 * size] = False  # between the samples: does not matter
    inside = auto._block_inside(mask, size)
    assert inside.shape == (5, 7) and inside.sum() == 5 * 7 - 1 and not inside[1, 2]


def test_block_means_take_blocks_of_whole_parts():
    with pytest.raises(AssertionError):
        auto._block_means(np.zeros((9, 9), np.float32), 3)


def test_the_reports_verdict_uses_autos_default_margin():
    """The report's verdict ("use ...") and ``apply --methods auto`` judge alike: one margin."""
    from sss_lab.core.study.report import VERDICT_MARGIN

    assert VERDICT_MARGIN == auto.DEFAULT_MAX_ERROR
