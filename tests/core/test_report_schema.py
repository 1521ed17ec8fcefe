"""The report's typed schema (core/study/report_schema.py) on the metrics.json core.study.report writes."""

import json

import numpy as np
import pytest

from sss_lab.core.study.report import write_report
from sss_lab.core.study.report_schema import Entry, Report


def _written(tmp_path):
    ref = np.random.default_rng(1).random((8, 8, 3)).astype(np.float32)
    entries = [
        {"name": "no SSS", "kind": "baseline", "time_s": {"total": 0.2}, "metrics": {"rel_rmse": 0.2, "ssim": 0.9}},
        {
            "name": "Burley samples=32",
            "kind": "technique",
            "technique": "burley",
            "quality": {"n_samples": 32},
            "time_s": {"total": 0.4, "apply": 0.2},
            "metrics": {"rel_rmse": 0.05, "ssim": 0.99},
        },
        {"name": "Cycles 16 spp", "kind": "cycles", "time_s": {"total": 3.0}, "metrics": {"rel_rmse": 0.04}},
    ]
    data = {"scene": {"name": "t"}, "settings": {"box": 1}, "noise_floor": {"rel_rmse": 0.01}, "entries": entries}
    data |= {"notes": ["STA not run: no thickness map"], "complete": False, "timings": {"passes": 0.2}}
    images = {"Cycles reference": ref, "no SSS": ref * 0.8, "Burley samples=32": ref, "Cycles 16 spp": ref * 1.01}
    write_report(str(tmp_path), data, images, reference="Cycles reference", mask=np.ones((8, 8), bool))
    return tmp_path / "metrics.json"


def test_the_written_report_reads_as_typed_data_and_back(tmp_path):
    path = _written(tmp_path)
    report = Report.read(path)
    assert [e.kind for e in report.entries] == ["baseline", "technique", "cycles"]
    burley = report.entry("Burley samples=32")
    assert (burley.technique, burley.quality, burley.rel_rmse) == ("burley", {"n_samples": 32}, 0.05)
    assert burley.extra["image"].startswith("images/")  # a field the schema does not name is kept
    assert report.pareto and [e.name for e in report.best_techniques] == ["Burley samples=32"]
    assert not report.complete and report.notes == ["STA not run: no thickness map"]
    assert report.noise_floor["rel_rmse"] == 0.01
    assert json.loads(report.to_json()) == json.loads(path.read_text())  # nothing lost either way


def test_a_malformed_report_is_one_clear_error(tmp_path):
    bad = tmp_path / "metrics.json"
    bad.write_text(json.dumps({"entries": [{"name": "x", "kind": "guess", "metrics": {}, "time_s": {}}]}))
    with pytest.raises(ValueError, match=r"metrics.json: report entry 'x': kind 'guess' is not one of"):
        Report.read(bad)
    with pytest.raises(ValueError, match="missing metrics, time_s"):
        Entry.from_dict({"name": "y", "kind": "technique"})
    with pytest.raises(KeyError, match="no entry 'z'"):
        Report.from_dict({"entries": []}).entry("z")
