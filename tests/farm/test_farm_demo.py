"""``make farm-demo`` end to end: the OpenJD job run by ``openjd run`` with SSS Lab's real command
line (bpy), small (3 frames in chunks of 2, 32 × 32, 4 pass samples, a reference of 2 seeds × 4
samples); then the same job again, which keeps every file and says so.
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from sss_lab.core.scene import exr

ROOT = Path(__file__).resolve().parents[2]
PARAMS = (
    "-p Frames=1-3 -p FramesPerTask=2 -p Resolution=32x32 -p PassSamples=4 -p Threads=1 "
    "-p Compare=yes -p CompareEevee=no -p ReferenceTasks=2 -p ReferenceSamples=4"
)

pytestmark = pytest.mark.slow


def _make_farm_demo(out: Path) -> subprocess.CompletedProcess:
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    env = dict(os.environ)
    env.pop("MAKEFLAGS", None)
    return subprocess.run(
        ["make", "-s", "farm-demo", f"FARM_OUT={out}", f"FARM_PARAMS={PARAMS}", f"PY={sys.executable}"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
        env=env,
    )


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("farm")
    first = _make_farm_demo(out)
    assert first.returncode == 0, first.stdout[-4000:] + first.stderr[-2000:]
    job = out / "job"
    stamps = {p: p.stat().st_mtime_ns for p in (job / "passes").iterdir()}
    second = _make_farm_demo(out)
    assert second.returncode == 0, second.stdout[-4000:] + second.stderr[-2000:]
    return {"job": job, "first": first.stdout, "second": second.stdout, "stamps": stamps}


def test_every_frame_gets_passes_and_an_sss_exr(runs):
    passes = runs["job"] / "passes"
    for frame in (1, 2, 3):
        exr_path = passes / f"passes_{frame:04d}.exr"
        assert exr_path.is_file() and (passes / f"passes_{frame:04d}.json").is_file()
        layers = exr.read_layers(passes / f"passes_{frame:04d}.sss.exr").layers
        assert {"SSSLab.burley.Image", "SSSLab.ssss.Image", "SSSLab.sta.Image"} <= set(layers)
        assert f"Saved: '{exr_path}'" in runs["first"]
    assert re.search(r"frame 3 done in [\d.]+ s \(\d/\d, elapsed [\d.:]+( s)?, ETA", runs["first"])


def test_the_reference_is_rendered_in_seed_parts_merged_and_compared(runs):
    job = runs["job"]
    assert sorted(p.name for p in (job / "reference").glob("reference_seed_*.exr")) == [
        "reference_seed_00001.exr",
        "reference_seed_00002.exr",
    ]
    assert (job / "reference" / "reference.exr").is_file()
    report = (job / "compare" / "report.md").read_text(encoding="utf-8")
    assert "8 samples" in report and "halves" in report


def test_a_second_run_skips_what_exists_and_says_so(runs):
    second = runs["second"]
    for frame in (1, 2, 3):
        assert re.search(rf"render: \[\d/\d\] frame {frame}: skipped", second), second[-3000:]
        assert re.search(rf"apply: \[\d/\d\] frame {frame}: skipped", second)
    assert "seed 1: skipped" in second and "seed 2: skipped" in second
    assert "rendering" not in second.split("Running step 'Compare'")[0]  # nothing before Compare rendered again
    assert {p: p.stat().st_mtime_ns for p in runs["stamps"]} == runs["stamps"]
