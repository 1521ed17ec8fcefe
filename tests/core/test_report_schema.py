"""The report's typed schema (core/study/report_schema.py) on the metrics.json core.study.report writes."""

import json
import os

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


def _schema_errors(value, schema, root, where="metrics.json") -> list[str]:
    """The JSON Schema keywords docs/metrics.schema.json uses (type, enum, required, properties,
    items, additionalProperties, minimum, anyOf, $ref), checked without a dependency."""
    if "$ref" in schema:
        schema = root["$defs"][schema["$ref"].rsplit("/", 1)[1]]
    if "anyOf" in schema:
        if all(_schema_errors(value, s, root, where) for s in schema["anyOf"]):
            return [f"{where}: matches none of anyOf"]
        return []
    kinds = {"object": dict, "array": list, "string": str, "boolean": bool, "null": type(None)}
    types = schema.get("type")
    if types is not None:
        names = [types] if isinstance(types, str) else types

        def fits(t):
            if t == "integer":
                return isinstance(value, int) and not isinstance(value, bool)
            if t == "number":
                return isinstance(value, (int, float)) and not isinstance(value, bool)
            return isinstance(value, kinds[t])

        if not any(fits(t) for t in names):
            return [f"{where}: {type(value).__name__} is not {names}"]
    if "enum" in schema and value not in schema["enum"]:
        return [f"{where}: {value!r} is not one of {schema['enum']}"]
    errors = []
    if isinstance(value, (int, float)) and not isinstance(value, bool) and "minimum" in schema:
        if value < schema["minimum"]:
            errors.append(f"{where}: {value} < {schema['minimum']}")
    if isinstance(value, dict):
        errors += [f"{where}: missing {k!r}" for k in schema.get("required", []) if k not in value]
        for k, v in value.items():
            sub = schema.get("properties", {}).get(k, schema.get("additionalProperties"))
            if isinstance(sub, dict):
                errors += _schema_errors(v, sub, root, f"{where}.{k}")
    if isinstance(value, list) and "items" in schema:
        for i, v in enumerate(value):
            errors += _schema_errors(v, schema["items"], root, f"{where}[{i}]")
    return errors


def test_a_written_metrics_json_follows_the_published_schema(tmp_path):
    import numpy as np

    from sss_lab.core.study.report import write_report

    root = os.path.join(os.path.dirname(__file__), "..", "..", "docs", "metrics.schema.json")
    with open(root, encoding="utf-8") as fh:
        schema = json.load(fh)
    rng = np.random.default_rng(1)
    ref = rng.random((8, 8, 3)).astype(np.float32)

    def entry(name, kind, err, seconds, **extra):
        return {
            "name": name,
            "kind": kind,
            "metrics": {"rel_rmse": err, "rmse": err / 3, "ssim": 0.9},
            "time_s": {"total": seconds, "apply": seconds / 10, "sss_effect": seconds / 10},
            **extra,
        }

    entries = [
        entry("no SSS", "baseline", 0.3, 0.5),
        entry("Burley", "technique", 0.1, 0.6, technique="burley", quality={"n_samples": 16}),
        entry("Cycles 16 spp + OIDN", "cycles", 0.08, 0.9),
    ]
    images = {"Cycles reference": ref, **{e["name"]: ref * 1.1 for e in entries}}
    data = {
        "scene": {"name": "s"},
        "settings": {"reference_samples": 64, "pass_samples": 8, "box": 1},
        "entries": entries,
        "noise_floor": {"rel_rmse": 0.02},
        "complete": True,
        "notes": [],
    }
    write_report(str(tmp_path), data, images, reference="Cycles reference", summary=["Burley"])
    written = json.loads((tmp_path / "metrics.json").read_text())
    assert _schema_errors(written, schema, schema) == []
    # The check can fail: a row of an unknown kind, a verdict without its choice.
    written["entries"][0]["kind"] = "render"
    del written["verdict"][0]["use"]
    errors = _schema_errors(written, schema, schema)
    assert any("entries[0].kind" in e for e in errors) and any("missing 'use'" in e for e in errors)
