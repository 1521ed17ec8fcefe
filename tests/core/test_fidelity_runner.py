"""The fidelity runner's arithmetic (benchmarks/fidelity/run.py), without Blender."""

import pytest

from benchmarks.fidelity import run


def _scene(name, kind, none, **errors):
    rows = [{"technique": "none", "label": "no SSS", "default": True, "rel_rmse": none, "removed": 0.0}]
    for t, e in errors.items():
        rows.append({"technique": t, "label": t, "default": True, "rel_rmse": e, "removed": 1 - e / none})
    return {"scene": name, "kind": kind, "noise_floor": 0.02, "reference_noise": 0.01, "rows": rows}


def test_summary_medians_and_checks():
    results = [
        _scene("a", "diffusion", 0.2, ssss=0.1, burley=0.12),
        _scene("b", "diffusion", 0.1, ssss=0.08, burley=0.07),
        _scene("c", "diffusion", 0.1, ssss=0.115, burley=0.1),
        _scene("d", "backlit", 1.0, sta=0.4, ssss=1.0),
    ]
    s = run.summarize(results)
    diff = s["kinds"]["diffusion"]
    assert diff["median_removed_by_technique"]["ssss"] == pytest.approx(0.2)
    assert diff["median_removed_by_technique"]["burley"] == pytest.approx(0.3)
    assert diff["best_technique"] == "burley"
    assert s["kinds"]["backlit"]["best_technique"] == "sta"
    # SSSS on "c" is worse than no SSS by 0.015, more than the reference noise 0.01.
    assert [(w["scene"], w["label"]) for w in s["worse_than_no_sss"]] == [("c", "ssss")]
    assert s["burley_vs_ssss"]["scenes_burley_better_or_equal"] == 2


def test_the_held_out_scenes_are_summarized_apart():
    results = [
        _scene("a", "diffusion", 0.2, ssss=0.1),
        _scene("b", "diffusion", 0.1, ssss=0.08),
        {**_scene("c", "diffusion", 0.1, ssss=0.05), "held_out": True},
        _scene("d", "backlit", 1.0, ssss=0.4),
    ]
    kinds = run.summarize(results)["kinds"]
    assert kinds["diffusion"]["scenes"] == 3
    assert kinds["diffusion, held out"]["scenes"] == 1
    assert kinds["diffusion, held out"]["median_removed_by_technique"]["ssss"] == pytest.approx(0.5)
    assert kinds["diffusion, the rest"]["median_removed_by_technique"]["ssss"] == pytest.approx(0.35)
    assert "backlit, held out" not in kinds  # no held-out back-lit scene: no such group


def test_a_third_of_the_suite_is_held_out_by_name_alone():
    """The rule depends on the name only (the same on every machine and run) and keeps about a
    third of the suite, of both kinds, out of the fits."""
    from benchmarks.fidelity.scenes import SCENES, held_out

    out = [n for n in SCENES if held_out(n)]
    assert len(SCENES) / 4 <= len(out) <= len(SCENES) / 2
    assert {SCENES[n].kind for n in out} == {SCENES[n].kind for n in SCENES}
    assert all(SCENES[n].held_out == held_out(n) for n in SCENES)
