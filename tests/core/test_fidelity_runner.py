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
