"""core/pipeline/auto.py as a chooser of qualities (``choose(rungs=True)``, ``apply --auto-rungs``): each rung
of a technique's quality ladder (and each diffusion without its energy stage) is a candidate with its own
coefficients and cost rate. By default only the techniques' default qualities are candidates.

Expected values come from the specs' own ladders, ``core.pipeline.apply.apply`` run with the rung's
options for the composite, and models made up by hand so that the choice is known in advance."""

import dataclasses
import math

import numpy as np
import pytest

from sss_lab.core.base.errors import InputError
from sss_lab.core.pipeline import apply as core_apply
from sss_lab.core.pipeline import auto
from sss_lab.core.scene.exr import Passes
from sss_lab.core.study.synthetic import sphere_scene
from sss_lab.core.techniques.registry import TECHNIQUES, get_spec


def _scene(distance=0.5):
    arrays, scene = sphere_scene(64, 48)
    mats = tuple(dataclasses.replace(m, thickness_distance=distance) if m.scatters else m for m in scene.materials)
    return Passes(arrays), dataclasses.replace(scene, materials=mats)


def _model(coefficients: dict, rates: dict | None = None) -> auto.Model:
    return auto.Model({"none": (1.0, 1.0, 0.0), **coefficients}, command="test", seconds_per_work=rates or {})


def test_every_rung_of_every_ladder_is_a_candidate_and_the_default_is_the_techniques_name():
    for t in TECHNIQUES:
        spec = get_spec(t)
        runs = auto.variants(t)
        with_energy = "energy" in spec.keywords
        assert len(runs) == len(spec.qualities) * (2 if with_energy else 1)
        # The default rung runs with no options: the spec's defaults are that rung's values.
        assert runs[t] == {}
        assert all(spec.defaults[k] == v for k, v in spec.default_run.items())
        for k, rung in enumerate(spec.qualities):
            if k != spec.default_quality:
                assert auto.candidate_name(t, rung) in runs
            if with_energy:
                off = {**({} if k == spec.default_quality else rung), **auto.ENERGY_OFF}
                assert runs[auto.candidate_name(t, off)] == off
        for name, options in runs.items():
            assert auto.options_of(name) == options and auto.technique_of(name) == t
    assert auto.variants("burley")["burley n_samples=16 energy=lambert"] == {"n_samples": 16, "energy": "lambert"}


@pytest.mark.parametrize(
    "name, message",
    [
        ("burley n_samples=7", "not a rung of burley's quality ladder"),
        ("burley energy=view", "not a rung of burley's quality ladder"),
        ("sta energy=lambert", "not a rung of sta's quality ladder"),
        ("blur n_taps=3", "no technique 'blur'"),
    ],
)
def test_an_unknown_rung_in_a_stored_model_is_one_clear_error(name, message):
    with pytest.raises(InputError, match=message) as err:
        auto.Model.from_dict({"coefficients": {"none": [1, 1, 0], name: [0.2, 1, 0]}}, "my_model.json")
    assert "my_model.json" in str(err.value) and repr(name) in str(err.value)
    with pytest.raises(InputError, match=message):
        auto.Model.from_dict({"coefficients": {"none": [1, 1, 0]}, "seconds_per_work": {name: 1.0}})
    assert auto.Model.from_dict({"coefficients": {"none": [1, 1, 0], "burley n_samples=16": [0.2, 1, 0]}})


def test_the_cheapest_rung_within_the_margin_is_taken_and_run_with_its_options():
    passes, scene = _scene()
    # Burley at 8 samples predicted 4 % worse than at its default, 32 samples, with a quarter of the
    # work at the same rate: within 5 %, cheaper.
    model = _model({"burley": (0.19, 1.0, 0.0), "burley n_samples=8": (0.19 * 1.04**2, 1.0, 0.0)}, {"burley": 1.0})
    plan = auto.choose(passes, scene, model=model, max_error=0.05, techniques=("burley",), rungs=True)
    assert set(plan.chosen.values()) == {"burley n_samples=8"}, plan.explain()
    assert set(plan.plans) == {"burley n_samples=8"}
    (p,) = plan.plans.values()
    assert all(mp.params["n_samples"] == 8 for mp in p.applied)
    for c in plan.choices:
        by = {k.name: k for k in c.candidates}
        assert by["burley n_samples=8"].work == pytest.approx(by["burley"].work / 4)
        assert "n_samples=8 instead of burley's default" in c.reason
        # The rungs the model has no coefficients for are listed as such, never chosen.
        assert "burley n_samples=16" in c.unmodelled and "burley n_samples=16" not in by
    text = plan.explain()
    assert "=> burley n_samples=8:" in text
    assert "the auto model has no coefficients for them: " in text and "burley n_samples=64 energy=lambert" in text
    out = auto.apply_auto(passes, scene, prepared=plan)
    ref = core_apply.apply(passes, scene, "burley", n_samples=8)
    np.testing.assert_array_equal(out["SSSLab.auto.Image"], ref["SSSLab.burley.Image"])
    np.testing.assert_array_equal(out["SSSLab.auto.SSS"], ref["SSSLab.burley.SSS"])
    # With no margin the default's lower prediction wins.
    strict = auto.choose(passes, scene, model=model, max_error=0.0, techniques=("burley",), rungs=True)
    assert set(strict.chosen.values()) == {"burley"}


def test_two_rungs_of_one_technique_on_two_materials_composite_each_with_its_own_options():
    passes, scene = _scene()
    # The energy stage off, at the same work and half the rate, predicted worse by epsilon V^2: some
    # 4 % worse where V is small against the error (Skin), beyond the margin of 5 % where it is
    # large (Wax).
    feats = {m.name: auto.features(passes, scene, m) for m in scene.materials if m.scatters}
    base = _model({"burley": (0.19, 1.0, 0.0)})
    e2 = {n: base.predict("burley", f) ** 2 for n, f in feats.items()}
    eps = 0.08 * e2["Skin"] / feats["Skin"].view ** 2
    assert math.sqrt(1.0 + eps * feats["Wax"].view ** 2 / e2["Wax"]) > 1.05
    coefficients = {"burley": (0.19, 1.0, 0.0), "burley energy=lambert": (0.19, 1.0, 0.0, 0.0, eps)}
    model = _model(coefficients, {"burley": 2.0, "burley energy=lambert": 1.0})
    plan = auto.choose(passes, scene, model=model, max_error=0.05, techniques=("burley",), rungs=True)
    assert plan.chosen == {"Skin": "burley energy=lambert", "Wax": "burley"}, plan.explain()
    skin = next(c for c in plan.choices if c.features.name == "Skin")
    assert f"the energy stage off (energy V {feats['Skin'].view:.4f}" in skin.reason
    out = auto.apply_auto(passes, scene, prepared=plan)
    index = np.rint(passes["Material Index"])
    for name, options in (("Skin", auto.ENERGY_OFF), ("Wax", {})):
        ref = core_apply.apply(passes, scene, "burley", **options)
        sel = index == next(m.index for m in scene.materials if m.name == name)
        np.testing.assert_array_equal(out["SSSLab.auto.SSS"][sel], ref["SSSLab.burley.SSS"][sel])
        np.testing.assert_array_equal(out["SSSLab.auto.Image"][sel], ref["SSSLab.burley.Image"][sel])
    # A later frame keeps the rungs (the choice of a sequence's first frame, by candidate name).
    flipped = _model(coefficients, {"burley": 1.0, "burley energy=lambert": 2.0})
    assert auto.choose(passes, scene, model=flipped, techniques=("burley",)).chosen["Skin"] == "burley"
    kept = auto.choose(passes, scene, model=flipped, techniques=("burley",), keep=plan.chosen, rungs=True)
    assert kept.chosen == plan.chosen and "kept from the first frame" in kept.choices[0].reason


def test_rungs_of_one_technique_rank_by_cost_without_the_tolerance_between_techniques():
    passes, scene = _scene()
    # SSSS at 11 taps estimated 5 % cheaper than at 17 (inside COST_TOLERANCE) and predicted 2 %
    # worse: between rungs of one technique the cheaper one within the margin is taken.
    skin = next(m for m in scene.materials if m.name == "Skin")
    pixels = auto.features(passes, scene, skin).pixels
    w17, w11 = (auto._work("ssss", skin, pixels, 0, None, o) for o in ({}, {"n_taps": 11}))
    rates = {"ssss": 1.0 / w17, "ssss n_taps=11": 0.95 / w11}
    model = _model({"ssss": (0.2, 1.0, 0.0), "ssss n_taps=11": (0.2 * 1.02**2, 1.0, 0.0)}, rates)
    plan = auto.choose(passes, scene, model=model, max_error=0.05, techniques=("ssss",), rungs=True)
    assert plan.chosen["Skin"] == "ssss n_taps=11", plan.explain()


def test_a_fits_measurement_of_the_default_is_scaled_to_its_rungs_by_the_prediction():
    passes, scene = _scene()
    fit = {
        t: {"gain": (1.0, 1.0, 1.0), "info": {"samples": 32, "heldout_after": e}}
        for t, e in (("burley", 0.100), ("combined", 0.098))
    }
    measured = dataclasses.replace(
        scene, materials=tuple(dataclasses.replace(m, fit=fit) if m.scatters else m for m in scene.materials)
    )
    model = _model(
        {
            "burley": (0.19, 1.0, 0.0),
            "burley n_samples=16": (0.19 * 1.01**2, 1.0, 0.0),
            "combined": (0.19, 1.0, 0.0),
            "ssss": (0.19, 1.0, 0.0),
        },
        {"burley": 1.0, "combined": 3.0, "ssss": 0.5},
    )
    plan = auto.choose(passes, measured, model=model, max_error=0.05, rungs=True)
    for c in plan.choices:
        by = {k.name: k for k in c.candidates}
        rung = by["burley n_samples=16"]
        assert rung.measured is None and rung.excluded is None
        assert rung.scaled == pytest.approx(0.100 * rung.predicted / by["burley"].predicted)
        assert by["ssss"].excluded and "not measured by the material's fit" in by["ssss"].excluded
        # At most 0.101 <= 1.05 x 0.098, and half of Burley's default work: the rung.
        assert c.chosen == "burley n_samples=16", plan.explain()
        assert "the rung's error scaled by the predicted ratio" in c.reason
    assert "from burley's measured error x the predicted ratio" in plan.explain()


def test_train_learns_each_rung_from_its_own_errors_and_times():
    rng = np.random.default_rng(7)
    truth = {"none": (1.0, 1.0, 0.001), "burley": (0.2, 1.0, 0.002), "burley n_samples=8": (0.3, 1.0, 0.004)}
    samples = []
    for i in range(12):
        f = auto.Features(name=f"m{i}", index=1, pixels=100, diffusion=float(rng.random()), back=float(rng.random()))
        if i % 3 == 0:  # fitted for burley: its energy term is not added to burley's rungs either
            f = dataclasses.replace(f, fitted=("burley",), energy=0.1)
        errors = {t: math.sqrt(a * f.diffusion**2 + b * f.back**2 + c) for t, (a, b, c) in truth.items()}
        errors["none"] = math.sqrt(errors["none"] ** 2 + f.energy**2)
        samples.append((f, errors))
    timings = [("burley", 100.0, 1.0), ("burley n_samples=8", 25.0, 0.5)]
    model = auto.train(samples, timings=timings)
    for t, coef in truth.items():
        np.testing.assert_allclose(model.coefficients[t][:3], coef, atol=1e-9)
    assert model.seconds_per_work == {"burley": pytest.approx(0.01), "burley n_samples=8": pytest.approx(0.02)}
    # A rung without a measured rate counts at its technique's.
    assert model.seconds("burley n_samples=16", 50.0) == pytest.approx(0.5)
    again = auto.Model.from_dict(model.to_dict())
    assert again.coefficients == model.coefficients and again.seconds_per_work == model.seconds_per_work


def test_the_shipped_model_knows_every_rung_and_how_it_was_made():
    shipped = auto.load_model()
    for t in (t for t, spec in TECHNIQUES.items() if spec.auto):
        for name in auto.variants(t):
            assert name in shipped.coefficients, name
            assert name in shipped.seconds_per_work, name
    assert "benchmarks.auto" in shipped.command and len(shipped.trained_on) >= 10


def test_a_technique_its_spec_keeps_out_of_auto_is_not_a_candidate(monkeypatch):
    passes, scene = _scene()
    model = _model({"burley": (0.19, 1.0, 0.0), "ssss": (0.01, 0.01, 0.0)}, {"burley": 1.0, "ssss": 1.0})
    kept_out = dataclasses.replace(get_spec("ssss"), auto=False)
    monkeypatch.setattr(auto, "get_spec", lambda t: kept_out if t in ("ssss", kept_out) else get_spec(t))
    plan = auto.choose(passes, scene, model=model, techniques=("burley", "ssss"), rungs=True)
    assert set(plan.chosen.values()) == {"burley"}, plan.explain()
    for c in plan.choices:
        (ssss,) = [k for k in c.candidates if k.technique == "ssss"]
        assert ssss.name == "ssss" and "auto=False" in ssss.excluded
    assert "ssss" in plan.explain() and "not a candidate: its spec keeps it out of auto" in plan.explain()


def test_command_line_explain_lists_the_rungs_and_the_chosen_one(tmp_path, capsys):
    from sss_lab.addon.cli import main
    from sss_lab.core.study.synthetic import write_scene

    arrays, scene = sphere_scene(64, 48)
    path = write_scene(str(tmp_path / "passes.exr"), arrays, scene)
    assert main(["apply", path, "--methods", "auto", "--auto-rungs", "--explain"]) == 0
    out = capsys.readouterr().out
    plan = auto.choose(Passes(arrays), scene, rungs=True)
    for c in plan.choices:
        assert f"=> {c.chosen}: " in out
        for k in c.candidates:
            assert k.name in out
    assert all(name in out for name in auto.variants("burley"))


def test_a_fitted_technique_keeps_its_energy_stage():
    passes, scene = _scene()
    fit = {"burley": {"gain": (1.0, 1.0, 1.0), "info": {"samples": 32, "heldout_after": 0.1}}}
    fitted = dataclasses.replace(
        scene, materials=tuple(dataclasses.replace(m, fit=fit) if m.scatters else m for m in scene.materials)
    )
    # The energy stage off predicted far better and cheaper: still not a candidate for the fitted Burley
    # (its gain was fitted on top of the stage), while SSSS without the stage is.
    off = (0.01, 0.0, 0.0)
    model = _model(
        {"burley": (0.19, 1.0, 0.0), "burley energy=lambert": off, "ssss": (0.2, 1.0, 0.0), "ssss energy=lambert": off},
        {"burley": 1.0, "burley energy=lambert": 0.5, "ssss": 1.0, "ssss energy=lambert": 0.5},
    )
    plan = auto.choose(passes, fitted, model=model, techniques=("burley", "ssss"), rungs=True)
    for c in plan.choices:
        by = {k.name: k for k in c.candidates}
        assert "made with its energy stage on" in by["burley energy=lambert"].excluded
        assert by["ssss energy=lambert"].excluded is None
        assert c.chosen == "ssss energy=lambert", plan.explain()
    unfitted = auto.choose(passes, scene, model=model, techniques=("burley", "ssss"), rungs=True)
    assert all(k.excluded is None for c in unfitted.choices for k in c.candidates)


def test_by_default_the_candidates_are_the_techniques_at_their_default_quality(tmp_path, capsys):
    """Without ``rungs`` no rung is a candidate, even one the model predicts better and cheaper, and
    the plan says so; ``apply --auto-rungs`` turns them on, and only with ``--methods auto``."""
    from sss_lab.addon.cli import main
    from sss_lab.core.study.synthetic import write_scene

    passes, scene = _scene()
    model = _model(
        {"burley": (0.19, 1.0, 0.0), "burley n_samples=8": (0.01, 0.0, 0.0)},
        {"burley": 1.0, "burley n_samples=8": 0.25},
    )
    plan = auto.choose(passes, scene, model=model, techniques=("burley",))
    assert set(plan.chosen.values()) == {"burley"}, plan.explain()
    assert {k.name for c in plan.choices for k in c.candidates} == {"none", "burley"}
    assert "at its default quality" in plan.explain() and not plan.rungs and plan.to_dict()["rungs"] is False
    with_rungs = auto.choose(passes, scene, model=model, techniques=("burley",), rungs=True)
    assert set(with_rungs.chosen.values()) == {"burley n_samples=8"}, with_rungs.explain()
    assert "or rung of its quality ladder" in with_rungs.explain()
    arrays, described = sphere_scene(64, 48)
    path = write_scene(str(tmp_path / "passes.exr"), arrays, described)
    assert main(["apply", path, "--methods", "auto", "--explain"]) == 0
    out = capsys.readouterr().out
    assert "burley n_samples=8" not in out and "at its default quality" in out
    assert main(["apply", path, "--methods", "burley", "--auto-rungs", "--explain"]) != 0
    assert "--auto-rungs: only --methods auto takes it" in capsys.readouterr().err
