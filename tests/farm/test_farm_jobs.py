"""The farm job formats: the Open Job Description template and the Flamenco job type.

Without Blender: ``openjd check`` validates the template; ``openjd run`` runs it with a stand-in
for SSS Lab's command line that records its arguments; the Flamenco job type's ``compileJob``
runs under Node.js against a stub of Flamenco's ``author`` API (tests/farm/flamenco_harness.js).
Both must give the same commands, task for task.
"""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from sss_lab.core.pipeline.sequence import parse_frames

ROOT = Path(__file__).resolve().parents[2]
TEMPLATE = ROOT / "farm" / "openjd" / "template.yaml"
FLAMENCO = ROOT / "farm" / "flamenco" / "sss_lab.js"
HARNESS = Path(__file__).with_name("flamenco_harness.js")
OPENJD = Path(sys.executable).with_name("openjd")

SCENE = "/farm/scenes/shot 1.blend"  # a space: the scripts must quote paths
OUT = "/farm/out/shot 1"
SMALL = {"Frames": "1-5", "FramesPerTask": 2, "Resolution": "32x32", "PassSamples": 8, "Threads": 1}
REFERENCE = {"ReferenceTasks": 3, "ReferenceSamples": 4}

RECORDER = """import json, sys
with open(sys.argv[1], "a", encoding="utf-8") as fh:
    fh.write(json.dumps({"who": sys.argv[2], "argv": sys.argv[3:]}) + "\\n")
"""


def openjd(*args, cwd=None):
    assert OPENJD.exists(), f"{OPENJD} is missing: the test set-up installs openjd-cli (requirements.txt)"
    return subprocess.run([str(OPENJD), *args], capture_output=True, text=True, cwd=cwd, timeout=300)


def params(values: dict) -> list[str]:
    return [arg for key, value in values.items() for arg in ("-p", f"{key}={value}")]


def test_openjd_check_accepts_the_template():
    run = openjd("check", str(TEMPLATE))
    assert run.returncode == 0, run.stdout + run.stderr
    assert "passes validation" in run.stdout


def test_openjd_check_rejects_a_broken_template(tmp_path):
    """The check is a real one: a step depending on a step that does not exist fails it."""
    broken = tmp_path / "template.yaml"
    broken.write_text(TEMPLATE.read_text().replace("dependsOn: RenderPasses", "dependsOn: RenderPasess"))
    assert openjd("check", str(broken)).returncode != 0


def _openjd_commands(tmp_path, compare: bool, extra: dict | None = None) -> list[dict]:
    """Run the whole template with the recorder as SSS Lab: one entry per command a task ran."""
    recorder = tmp_path / "recorder.py"
    recorder.write_text(RECORDER)
    log = tmp_path / "argv.jsonl"
    values = {
        "SceneFile": SCENE,
        "OutputDir": OUT,
        "SSSLab": f"{sys.executable} {recorder} {log} blender",
        "SSSLabNumpy": f"{sys.executable} {recorder} {log} numpy",
        **SMALL,
        **REFERENCE,
        "Compare": "yes" if compare else "no",
        **(extra or {}),
    }
    run = openjd("run", str(TEMPLATE), "--step", "Compare", "--run-dependencies", *params(values), cwd=tmp_path)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []


def _normal(argv: list[str]) -> tuple:
    """An argument list with --frames as a set of frames (OpenJD writes a chunk as 1,2 and
    Flamenco's frameChunker as 1-2)."""
    out = list(argv)
    if "--frames" in out:
        i = out.index("--frames") + 1
        out[i] = tuple(parse_frames(out[i]))
    return tuple(out)


def test_openjd_job_runs_every_step_with_the_commands_of_the_readme(tmp_path):
    calls = _openjd_commands(tmp_path, compare=True)
    by_command = {}
    for c in calls:
        by_command.setdefault(c["argv"][0], []).append(c)
    assert sorted(by_command) == ["apply", "compare", "merge-reference", "reference", "render"]
    # Frames 1-5 in chunks of 2: three render and three apply tasks covering every frame once.
    renders = [c["argv"] for c in by_command["render"]]
    frames = sorted(f for a in renders for f in parse_frames(a[a.index("--frames") + 1]))
    assert frames == [1, 2, 3, 4, 5] and len(renders) == 3
    assert all(c["who"] == "blender" for c in by_command["render"] + by_command["reference"] + by_command["compare"])
    assert all(c["who"] == "numpy" for c in by_command["apply"] + by_command["merge-reference"])
    assert renders[0][:3] == ["render", SCENE, "--out"] and renders[0][3] == f"{OUT}/passes"
    for a in renders:
        assert a[a.index("--resolution") + 1] == "32x32" and "--skip-existing" in a
    seeds = sorted(int(c["argv"][c["argv"].index("--seeds") + 1]) for c in by_command["reference"])
    assert seeds == [1, 2, 3]
    # The order of the steps: apply after render, merge after the parts, compare last.
    order = [c["argv"][0] for c in calls]
    assert max(i for i, n in enumerate(order) if n == "render") < min(i for i, n in enumerate(order) if n == "apply")
    assert max(i for i, n in enumerate(order) if n == "reference") < order.index("merge-reference")
    assert order[-1] == "compare"


def test_openjd_job_without_compare_renders_no_reference(tmp_path):
    calls = _openjd_commands(tmp_path, compare=False)
    assert sorted({c["argv"][0] for c in calls}) == ["apply", "render"]


def _flamenco_tasks(settings: dict) -> dict:
    node = shutil.which("node") or shutil.which("nodejs")
    if node is None:
        pytest.skip("Node.js is not installed: the Flamenco job type cannot be compiled here")
    run = subprocess.run(
        [node, str(HARNESS), str(FLAMENCO), json.dumps(settings)], capture_output=True, text=True, timeout=60
    )
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout)


FLAMENCO_SETTINGS = {
    "frames": SMALL["Frames"],
    "chunk_size": SMALL["FramesPerTask"],
    "output_root": OUT,
    "methods": "all",
    "pass_samples": SMALL["PassSamples"],
    "resolution": SMALL["Resolution"],
    "threads": SMALL["Threads"],
    "device": "CPU",
    "numpy_command": "python -m sss_lab",
    "compare": True,
    "compare_eevee": True,
    "compare_frame": 1,
    "reference_tasks": REFERENCE["ReferenceTasks"],
    "reference_samples": REFERENCE["ReferenceSamples"],
    "blendfile": SCENE,
}


def _flamenco_argv(task: dict) -> tuple[str, list[str]]:
    """(who, SSS Lab's arguments) of a task's one command, as the worker would run it."""
    (command,) = task["commands"]
    p = command["parameters"]
    if command["name"] == "blender-render":
        # The worker runs {exe} {exeArgs} {argsBefore} {blendfile} {args}.
        assert (p["exe"], p["exeArgs"]) == ("{blender}", "{blenderArgs}")
        assert p["argsBefore"][:2] == ["--command", "sss_lab"]
        return "blender", [*p["argsBefore"][2:], p["blendfile"], *p["args"]]
    assert command["name"] == "exec"
    assert [p["exe"], *p["args"][:2]] == ["python", "-m", "sss_lab"]
    return "numpy", p["args"][2:]


def test_flamenco_job_type_declares_its_settings():
    job = _flamenco_tasks(FLAMENCO_SETTINGS)
    assert job["label"] == "SSS Lab"
    keys = {s["key"] for s in job["settings"]}
    assert set(FLAMENCO_SETTINGS) <= keys
    assert all({"key", "type"} <= set(s) for s in job["settings"])


def test_flamenco_job_type_builds_the_commands_of_the_openjd_template(tmp_path):
    job = _flamenco_tasks(FLAMENCO_SETTINGS)
    flamenco = sorted((who, _normal(argv)) for who, argv in map(_flamenco_argv, job["tasks"]))
    openjd_calls = sorted((c["who"], _normal(c["argv"])) for c in _openjd_commands(tmp_path, compare=True))
    assert flamenco == openjd_calls
    deps = {t["name"]: set(t["dependencies"]) for t in job["tasks"]}
    applies = {n for n in deps if n.startswith("apply-")}
    assert all(deps[a] == {"render-" + a[len("apply-") :]} for a in applies)
    assert deps["merge-reference"] == {"reference-1", "reference-2", "reference-3"}
    assert deps["compare"] == {"merge-reference"} | applies


def test_eevee_can_be_left_out_of_the_farm_comparison_in_both_formats(tmp_path):
    """CompareEevee=no (OpenJD) and compare_eevee false (Flamenco) both give compare --no-eevee;
    by default neither does (the test above)."""
    job = _flamenco_tasks({**FLAMENCO_SETTINGS, "compare_eevee": False})
    (compare,) = [argv for who, argv in map(_flamenco_argv, job["tasks"]) if argv[0] == "compare"]
    openjd_calls = _openjd_commands(tmp_path, compare=True, extra={"CompareEevee": "no"})
    (openjd_compare,) = [c["argv"] for c in openjd_calls if c["argv"][0] == "compare"]
    assert compare[-1] == "--no-eevee" and openjd_compare[-1] == "--no-eevee"
    assert _normal(compare) == _normal(openjd_compare)


def test_flamenco_job_type_without_compare(tmp_path):
    job = _flamenco_tasks({**FLAMENCO_SETTINGS, "compare": False, "resolution": ""})
    names = [t["name"] for t in job["tasks"]]
    assert names == ["render-1-2", "apply-1-2", "render-3-4", "apply-3-4", "render-5", "apply-5"]
    _, argv = _flamenco_argv(job["tasks"][0])
    assert "--resolution" not in argv


def test_harness_runs_node_on_a_syntax_error(tmp_path):
    """A job type that does not parse fails the harness (so the tests above would see it)."""
    node = shutil.which("node") or shutil.which("nodejs")
    if node is None:
        pytest.skip("Node.js is not installed")
    bad = tmp_path / "bad.js"
    bad.write_text(FLAMENCO.read_text().replace("function compileJob(job) {", "function compileJob(job) {{"))
    run = subprocess.run([node, str(HARNESS), str(bad), "{}"], capture_output=True, text=True, timeout=60)
    assert run.returncode != 0 and "SyntaxError" in run.stderr
