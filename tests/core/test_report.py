"""The report: Pareto front, and pages whose numbers are the JSON's numbers."""

import json
import os

import numpy as np
import pytest

from sss_lab.core.study.report import pareto_front, report_files, write_report


def _entry(name, t, err, kind="technique"):
    return {"name": name, "kind": kind, "time_s": {"total": t, "apply": t / 2}, "metrics": {"rel_rmse": err}}


def test_pareto_front_keeps_only_undominated_entries():
    entries = [_entry("a", 1.0, 0.5), _entry("b", 2.0, 0.6), _entry("c", 3.0, 0.1), _entry("d", 0.5, 0.9)]
    # b is slower and worse than a; the others each win on time or error.
    assert pareto_front(entries) == ["d", "a", "c"]


def test_pareto_front_skips_entries_without_numbers():
    assert pareto_front([_entry("a", 1.0, None), _entry("b", 1.0, 0.2)]) == ["b"]


def test_report_pages_carry_the_json_numbers(tmp_path):
    rng = np.random.default_rng(0)
    ref = rng.random((8, 8, 3)).astype(np.float32)
    images = {"Cycles reference": ref, "burley n=32": ref * 1.05, "no SSS": ref * 0.8}
    entries = [_entry("burley n=32", 0.4, 0.0512345), _entry("no SSS", 0.2, 0.2012345, kind="baseline")]
    data = {"scene": {"name": "t"}, "settings": {"box": 1}, "entries": entries, "complete": True}
    out = write_report(
        str(tmp_path),
        data,
        images,
        reference="Cycles reference",
        mask=np.ones((8, 8), bool),
        summary=["no SSS", "Cycles reference", "not rendered"],
    )
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved["pareto"] == out["pareto"] == ["no SSS", "burley n=32"]
    md = (tmp_path / "report.md").read_text()
    html = (tmp_path / "report.html").read_text()
    for e in saved["entries"]:
        shown = f"{e['metrics']['rel_rmse']:.4g}"
        assert shown in md and shown in html
        assert os.path.isfile(tmp_path / e["image"]) and os.path.isfile(tmp_path / e["error_image"])
    assert "<svg" in html and (tmp_path / "grid.png").read_bytes()[:4] == b"\x89PNG"
    assert "incomplete" not in md
    # The grid's columns are named, and each picture is shown with its name.
    assert "Columns, left to right: Cycles reference, burley n=32, no SSS." in md
    for e in saved["entries"]:
        assert f'<img src="{e["image"]}" alt="{e["name"]}"' in html
    assert saved["reference_image"] == "images/Cycles_reference.png"
    # The summary keeps the asked columns that exist, in that order.
    assert saved["summary"]["columns"] == ["no SSS", "Cycles reference"]
    assert (tmp_path / "summary.png").read_bytes()[:4] == b"\x89PNG"
    # report_files names every file written (each gets its Saved line), report.html last.
    listed = report_files(str(tmp_path), out)
    on_disk = sorted(os.path.join(d, f) for d, _, fs in os.walk(tmp_path) for f in fs)
    assert sorted(listed) == on_disk and listed[-1].endswith("report.html")


def test_incomplete_report_says_so(tmp_path):
    ref = np.ones((4, 4, 3), np.float32)
    data = {"entries": [], "complete": False, "notes": ["scene has no camera"]}
    write_report(str(tmp_path), data, {"ref": ref}, reference="ref")
    assert "incomplete" in (tmp_path / "report.md").read_text()
    assert "scene has no camera" in (tmp_path / "report.html").read_text()


def test_missing_reference_image_is_named(tmp_path):
    with pytest.raises(ValueError, match="Cycles"):
        write_report(str(tmp_path), {}, {"a": np.ones((2, 2, 3))}, reference="Cycles")


def test_pareto_labels_do_not_overprint_when_points_cluster():
    # SSSS and Burley at nearly the same time and error (what the compare report met): every
    # label gets its own box, none covers a point, all stay inside the picture.
    import re

    from sss_lab.core.study.report import _label_box, _overlaps, pareto_svg

    names = ["SSSS taps=11", "SSSS taps=17", "SSSS taps=25", "Burley samples=16", "Burley samples=32", "STA"]
    entries = [
        {
            "name": n,
            "kind": "technique",
            "metrics": {"rel_rmse": 0.120 + 0.001 * i},
            "time_s": {"total": 3.0 + 0.01 * i},
        }
        for i, n in enumerate(names)
    ]
    entries.append({"name": "no SSS", "kind": "baseline", "metrics": {"rel_rmse": 0.2}, "time_s": {"total": 2.9}})
    svg = pareto_svg(entries, ["no SSS"])
    texts = re.findall(r'<text x="([\d.]+)" y="([\d.]+)" text-anchor="(start|end)">([^<]+)</text>', svg)
    labels = {t[3]: _label_box(float(t[0]), float(t[1]), t[2], t[3]) for t in texts if t[3] in {*names, "no SSS"}}
    assert set(labels) == {*names, "no SSS"}
    boxes = list(labels.values())
    for i, a in enumerate(boxes):
        assert 0 <= a[0] and a[2] <= 640 + 20 and 0 <= a[1] and a[3] <= 400
        assert not any(_overlaps(a, b) for b in boxes[i + 1 :])
    dots = [
        (float(x) - 4, float(y) - 4, float(x) + 4, float(y) + 4)
        for x, y in re.findall(r'<circle cx="([\d.]+)" cy="([\d.]+)"', svg)
    ]
    assert len(dots) == 7
    assert not any(_overlaps(a, d) for a in boxes for d in dots)


def test_the_report_breaks_the_error_down_per_material(tmp_path):
    ref = np.ones((8, 8, 3), np.float32)
    by = {"Skin": {"rel_rmse": 0.0312345}, "Wax": {"rel_rmse": 0.0712345}}
    entries = [{**_entry("burley n=32", 0.4, 0.05), "by_material": by}, _entry("no SSS", 0.2, 0.2, kind="baseline")]
    data = {"scene": {"name": "t"}, "settings": {"box": 1}, "entries": entries, "complete": True}
    write_report(str(tmp_path), data, {"ref": ref, "burley n=32": ref, "no SSS": ref}, reference="ref")
    md = (tmp_path / "report.md").read_text()
    html = (tmp_path / "report.html").read_text()
    assert "## Per material" in md and "| image | Skin | Wax |" in md
    assert "| burley n=32 | 0.03123 | 0.07123 |" in md and "| no SSS | — | — |" in md
    assert "<h2>Per material</h2>" in html and "0.07123" in html
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved["entries"][0]["by_material"] == by


def test_the_report_says_how_each_material_was_read(tmp_path):
    """A material's notes (an input read per pixel from the render, a Principled BSDF found behind
    a Mix Shader) are listed under "Materials as read"; a material without notes is not."""
    ref = np.ones((8, 8, 3), np.float32)
    notes = [
        "Principled BSDF 'Inner' reached through Group 'Asset' (1 of the surface)",
        "Base Color: read from the render ('SSSLab Base Color' AOV): median (0.4, 0.2, 0.1) over 900 pixels",
    ]
    materials = [{"name": "Skin", "notes": notes}, {"name": "Wax", "notes": []}]
    data = {"scene": {"name": "t", "materials": materials}, "settings": {"box": 1}, "complete": True}
    data["entries"] = [_entry("no SSS", 0.2, 0.2, kind="baseline")]
    write_report(str(tmp_path), data, {"ref": ref, "no SSS": ref}, reference="ref")
    md = (tmp_path / "report.md").read_text()
    assert "## Materials as read" in md
    assert f"- **Skin**: {notes[0]}; {notes[1]}." in md
    assert "**Wax**" not in md
    assert "<h2>Materials as read</h2>" in (tmp_path / "report.html").read_text()


def test_the_pareto_cost_is_the_sss_effects_own_with_its_spread(tmp_path):
    """A technique's cost is its own run (the median of its timed runs), not the passes' render
    that every technique shares; a peer's is its whole render."""
    from sss_lab.core.study.report import pareto_cost, pareto_svg

    fast = {"name": "Burley 8", "kind": "technique", "metrics": {"rel_rmse": 0.10}}
    fast["time_s"] = {"total": 0.34, "sss_effect": 0.002, "sss_effect_spread": [0.0018, 0.0031]}
    slow = {"name": "Burley 64", "kind": "technique", "metrics": {"rel_rmse": 0.09}}
    slow["time_s"] = {"total": 0.35, "sss_effect": 0.012, "sss_effect_spread": [0.011, 0.013]}
    peer = {"name": "Cycles 16 spp", "kind": "cycles", "metrics": {"rel_rmse": 0.05}, "time_s": {"total": 0.5}}
    assert [pareto_cost(e) for e in (fast, slow, peer)] == [0.002, 0.012, 0.5]
    assert pareto_front([fast, slow, peer]) == ["Burley 8", "Burley 64", "Cycles 16 spp"]
    svg = pareto_svg([fast, slow, peer], ["Burley 8", "Burley 64", "Cycles 16 spp"])
    assert "cost of the SSS effect" in svg and svg.count('stroke="#1f77b4"') == 2  # one spread bar each


def test_the_samples_axis_plots_samples_per_pixel_and_has_its_own_front():
    """Beside the seconds, a cost that does not depend on the machine: a technique's samples or taps
    per pixel and a render's samples; the baseline (no samples) is left out of that plot."""
    from sss_lab.core.study.report import pareto_svg, samples_cost

    def entry(name, kind, err, n):
        e = {"name": name, "kind": kind, "metrics": {"rel_rmse": err}, "time_s": {"total": 1.0}}
        if n:
            e["samples_per_pixel"] = n
        return e

    rows = [
        entry("no SSS", "baseline", 0.3, None),
        entry("Burley 8", "technique", 0.12, 8),
        entry("Burley 64", "technique", 0.10, 64),
        entry("SSSS 17", "technique", 0.15, 17),  # more samples than Burley 8 and a larger error: off the front
        entry("Cycles 4 spp", "cycles", 0.05, 4),
    ]
    assert [samples_cost(e) for e in rows] == [None, 8.0, 64.0, 17.0, 4.0]
    front = pareto_front(rows, cost=samples_cost)
    assert front == ["Cycles 4 spp"]  # 4 samples with the smallest error beat every other row
    svg = pareto_svg(rows, front, axis="pareto_samples.svg")
    assert "samples per pixel (log)" in svg and svg.count("<circle") == 4
    assert ">no SSS<" not in svg and 'stroke="#1f77b4"' not in svg  # no spread bars on this axis
