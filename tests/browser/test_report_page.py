"""The comparison report as a web page, opened in real headless Chromium (Debian's package).

The report is written by ``core.study.report.write_report`` from data shaped like a comparison's (a
baseline, techniques at several qualities, Cycles peers, the reference, the fidelity and
calibration tables, an incomplete-report note), then loaded at a phone's and a desktop's width.
Checked: every picture the page names loads, the inline Pareto plot renders with one dot per
measured entry (and the samples-per-pixel plot one per entry with samples), ``pareto.svg`` and
``pareto_samples.svg`` parse on their own, the console shows no error or warning and no
request fails, and the page never scrolls sideways (wide tables and pictures scroll inside
their own boxes) with text at a readable size. Screenshots of both widths go to
``$SSS_LAB_SCREENSHOTS`` when set (to look at them), else to the test's temporary folder.
"""

import os
import struct

import numpy as np

from sss_lab.core.study.report import write_report


def _comparison_like(folder):
    rng = np.random.default_rng(7)
    ref = rng.random((48, 64, 4)).astype(np.float32)
    mask = np.zeros((48, 64), bool)
    mask[8:40, 10:54] = True
    images, entries = {"Cycles reference": ref}, []

    def add(name, kind, error, seconds, **extra):
        images[name] = (ref * (1.0 + error)).astype(np.float32)
        entries.append(
            {
                "name": name,
                "kind": kind,
                "metrics": {"rel_rmse": error, "rmse": error / 3, "ssim": 1 - error},
                "time_s": {"total": seconds, "apply": seconds / 4 if kind == "technique" else None},
                **extra,
            }
        )

    add("no SSS", "baseline", 0.31, 0.8)
    add("STA", "technique", 0.2, 0.9, technique="sta", quality={}, samples_per_pixel=1)
    for taps, err in ((11, 0.12), (17, 0.1), (25, 0.095)):
        extra = {"technique": "ssss", "quality": {"n_taps": taps}, "samples_per_pixel": taps}
        add(f"SSSS taps={taps}", "technique", err, 0.8 + taps / 100, **extra)
    for n, err in ((8, 0.15), (32, 0.08)):
        extra = {"technique": "burley", "quality": {"n_samples": n}, "samples_per_pixel": n}
        add(f"Burley samples={n}", "technique", err, 1.0 + n / 50, **extra)
    add("Cycles 16 spp", "cycles", 0.09, 3.5, samples_per_pixel=16)
    add("Cycles Christensen-Burley 256 spp", "cycles", 0.06, 40.0, samples_per_pixel=256)
    data = {
        "scene": {"name": "head_frontlit.blend / Scene"},
        "settings": {"resolution": [64, 48], "reference_samples": 256, "pass_samples": 64, "seed": 0, "box": 2},
        "noise_floor": {"rel_rmse": 0.05, "ssim": 0.97},
        "entries": entries,
        "fidelity": {
            "definition": "Measured on a flat slab of the scene's widest material.",
            "rows": {"SSSS": {"r90_su": [0.3, 0.1, 0.05], "bleeding_ratio": 6.0, "energy_ratio": [1.0, 1.0, 0.99]}},
        },
        "calibration": {
            "definition": "Each mapping against the reference.",
            "rows": [
                {"method": "RANDOM_WALK", "technique": "ssss", "mapping": "a", "rel_rmse": 0.1, "chosen": True},
                {"method": "RANDOM_WALK", "technique": "ssss", "mapping": "b", "rel_rmse": 0.2},
            ],
        },
        "notes": ["a very long note naming a file /tmp/" + "x" * 120 + "/passes_0001.exr that must wrap"],
        "complete": False,
    }
    order = ["no SSS"] + [e["name"] for e in entries if e["name"] != "no SSS"] + ["Cycles reference"]
    return write_report(str(folder), data, images, reference="Cycles reference", mask=mask, order=order)


def _png_size(path):
    with open(path, "rb") as fh:
        head = fh.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n", path
    return struct.unpack(">II", head[16:24])


def test_report_page_loads_every_picture_and_reads_at_phone_and_desktop_widths(report_page, tmp_path):
    folder = str(tmp_path / "report")
    data = _comparison_like(folder)
    shots = os.environ.get("SSS_LAB_SCREENSHOTS") or str(tmp_path / "shots")
    seen = report_page.inspect(folder, screenshots=shots)
    assert report_page.problems(folder, seen) == []
    # The checks looked at something: every picture, a plot with a dot per measured entry, the text.
    for name, viewport in report_page.viewports.items():
        page = seen[name]
        # image + error map each, reference, grid, and the before/after viewer's two
        assert len(page["images"]) == 2 * len(data["entries"]) + 4, name
        assert page["svgs"][0]["circles"] == len(data["entries"]) == 9, name
        assert page["svgs"][1]["circles"] == 8, name  # every entry but "no SSS", which takes no samples
        assert "This report is incomplete" in page["text"] and "Pareto" in page["text"], name
        # The first screen answers which technique, at what error and cost, and what else was measured.
        first = page["first_screen"]
        assert "Verdict" in first and "use Burley samples=32" in first, (name, first)
        assert "removes 74 % of the no-SSS error" in first and "Best peer: Cycles Christensen-Burley" in first, (
            name,
            first,
        )
        width, height = _png_size(page["screenshot"])
        assert width == round(viewport["width"] * viewport["scale"]) and height > width / 2, (name, width, height)


def test_a_missing_picture_is_caught(report_page, tmp_path):
    """The check can fail: a report whose picture was deleted shows a failed load and a console error."""
    _comparison_like(tmp_path / "report")
    os.remove(tmp_path / "report" / "grid.png")
    seen = report_page.inspect(str(tmp_path / "report"))
    page = seen["desktop"]
    assert [img["src"] for img in page["images"] if not img["loaded"]] == ["grid.png"]
    assert page["failed"] and any("grid.png" in line for line in page["console"]), page["console"]
    problems = report_page.problems(str(tmp_path / "report"), seen)
    assert "desktop: picture did not load: grid.png" in problems and "phone: picture did not load: grid.png" in problems


def test_every_picture_links_to_its_full_size_and_the_viewer_slides_and_zooms(chromium, tmp_path):
    folder = tmp_path / "report"
    data = _comparison_like(folder)
    page = chromium.open("file://" + str(folder / "report.html"), width=1280, height=900)
    unlinked = page.evaluate(
        "Array.from(document.images).filter((i) => !i.closest('#viewer') &&"
        " !(i.closest('a') && i.closest('a').getAttribute('href') === i.getAttribute('src'))).length"
    )
    assert unlinked == 0
    pick = data["entries"][3]
    clip = page.evaluate(
        f"(() => {{ const v = document.getElementById('viewer'); const s = v.querySelector('select');"
        f" s.value = {pick['image']!r}; s.dispatchEvent(new Event('change'));"
        " const r = v.querySelector('input[type=range]'); r.value = 30; r.dispatchEvent(new Event('input'));"
        " const o = v.querySelector('img.over'); return [o.getAttribute('src'), o.style.clipPath]; })()"
    )
    assert clip == [pick["image"], "inset(0px 70% 0px 0px)"]
    widths = page.evaluate(
        "(() => { const st = document.querySelector('#viewer .stage'); const w0 = st.getBoundingClientRect().width;"
        " st.click(); const w1 = st.getBoundingClientRect().width; st.click();"
        " return [w0, w1, st.getBoundingClientRect().width]; })()"
    )
    assert widths[1] == 4 * widths[0] and widths[2] == widths[0]
    assert page.console == [] and page.failed == []
    page.send("Page.close")
