"""``python -m sss_lab apply`` as a render farm runs it: a subprocess in which importing bpy
fails, on passes written by core.scene.exr from the analytic scene of core/study/synthetic.py."""

import dataclasses
import hashlib
import os
import re
import subprocess
import sys

import numpy as np
import OpenEXR
import pytest

from sss_lab.core.scene.exr import read_layers, read_passes
from sss_lab.core.scene.scene import SceneDescription
from sss_lab.core.study.synthetic import sphere_scene, write_scene
from sss_lab.core.techniques.registry import TECHNIQUES

_RUN_WITHOUT_BPY = """
import runpy, sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('bpy', 'mathutils', 'bmesh', '_bpy'):
            raise ImportError(f'blocked import of {name}')
        return None
sys.meta_path.insert(0, Block())
sys.argv = ['sss_lab'] + sys.argv[1:]
runpy.run_module('sss_lab', run_name='__main__', alter_sys=True)
"""


def run_apply(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-c", _RUN_WITHOUT_BPY, "apply", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=300,
    )


def saved_lines(stdout):
    return re.findall(r"^Saved: '(.+)'$", stdout, flags=re.MULTILINE)


def digest(path):
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


@pytest.fixture
def passes_file(tmp_path):
    arrays, scene = sphere_scene()
    path = str(tmp_path / "passes.exr")
    write_scene(path, arrays, scene)
    return path, arrays, scene


def test_the_blocker_blocks_bpy(tmp_path):
    # Guards the tests below against a blocker that blocks nothing.
    code = _RUN_WITHOUT_BPY.replace("runpy.run_module('sss_lab', run_name='__main__', alter_sys=True)", "import bpy")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode != 0 and "blocked import of bpy" in proc.stderr


def test_round_trip_all_methods_without_bpy(passes_file):
    path, arrays, scene = passes_file
    before = digest(path)
    proc = run_apply(path, "--methods", "all")
    assert proc.returncode == 0, proc.stderr
    out = os.path.join(os.path.dirname(path), "passes.sss.exr")
    assert saved_lines(proc.stdout) == [out]
    assert digest(path) == before  # the input is untouched
    contents = read_layers(out)
    # The input layers are kept, and each technique adds its image and its SSS term.
    for name in arrays:
        np.testing.assert_array_equal(contents.layers[f"ViewLayer.{name}"], arrays[name])
    for technique in TECHNIQUES:
        image = contents.layers[f"SSSLab.{technique}.Image"]
        sss = contents.layers[f"SSSLab.{technique}.SSS"]
        assert image.shape == arrays["Combined"].shape and sss.shape == arrays["Diffuse Color"].shape
        plain = arrays["Material Index"] < 2  # the plane and the background do not scatter
        np.testing.assert_array_equal(image[plain], arrays["Combined"][plain])
        assert np.isfinite(image).all() and (sss[plain] == 0).all()
        assert np.abs(sss[~plain]).max() > 0, technique  # the spheres do change
    assert SceneDescription.from_json(contents.header["sss_lab.scene"]) == scene
    assert contents.half == set()  # float32 only
    # Blender's 5.2 reader sees the input view layer first, SSS Lab's layers apart.
    assert read_passes(out).view_layer == "ViewLayer"


def test_explain_prints_the_plan_and_writes_nothing(passes_file):
    path, _, _ = passes_file
    proc = run_apply(path, "--methods", "burley", "--explain")
    assert proc.returncode == 0, proc.stderr
    assert "'Skin'" in proc.stdout and "'Wax'" in proc.stdout and "Subsurface Weight is 0" in proc.stdout
    assert "pixels at the median depth" in proc.stdout
    assert saved_lines(proc.stdout) == []
    assert sorted(os.listdir(os.path.dirname(path))) == ["passes.exr", "passes.json"]


def test_frame_range_with_a_broken_frame(tmp_path):
    arrays, scene = sphere_scene(width=32, height=24)
    for frame in (1, 2, 3):
        write_scene(str(tmp_path / f"passes_{frame:04d}.exr"), arrays, dataclasses.replace(scene, frame=frame))
    (tmp_path / "passes_0002.exr").write_bytes(b"truncated by a crashed render node")
    proc = run_apply(tmp_path / "passes_####.exr", "--methods", "ssss", "--frames", "1-3")
    assert proc.returncode == 2  # the failed frame's input was bad (docs: 2 bad input, 1 failed write)
    assert saved_lines(proc.stdout) == [str(tmp_path / "passes_0001.sss.exr"), str(tmp_path / "passes_0003.sss.exr")]
    assert "[1/3] frame 1" in proc.stdout and "[3/3] frame 3" in proc.stdout
    assert "passes_0002.exr" in proc.stderr and "not a readable OpenEXR file" in proc.stderr
    assert "1 of 3 file(s) failed" in proc.stderr
    assert not (tmp_path / "passes_0002.sss.exr").exists()
    # Without --frames, the existing frames are found; written outputs are not overwritten.
    proc = run_apply(tmp_path / "passes_####.exr", "--methods", "ssss", "--out", tmp_path / "again_####.exr")
    assert proc.returncode == 2 and len(saved_lines(proc.stdout)) == 2
    assert (tmp_path / "again_0003.exr").exists()


def test_never_overwrites_the_input_or_an_existing_output(passes_file):
    path, _, _ = passes_file
    before = digest(path)
    proc = run_apply(path, "--methods", "burley", "--out", path)
    assert proc.returncode == 2 and "refusing to overwrite" in proc.stderr
    proc = run_apply(path, "--methods", "burley", "--out", path, "--overwrite")
    assert proc.returncode == 2 and "refusing to overwrite" in proc.stderr
    assert digest(path) == before
    assert run_apply(path, "--methods", "burley").returncode == 0
    proc = run_apply(path, "--methods", "burley")
    assert proc.returncode == 2 and "already exists" in proc.stderr  # as in every command
    proc = run_apply(path, "--methods", "burley", "--overwrite")
    assert proc.returncode == 0 and len(saved_lines(proc.stdout)) == 1


@pytest.mark.parametrize(
    "change", [{"subsurface_weight": 0.0}, {"subsurface_scale": 0.0}, {"subsurface_radius": (0.0, 0.0, 0.0)}]
)
def test_scene_without_sss_material_writes_nothing_and_names_the_input(tmp_path, change):
    arrays, scene = sphere_scene(width=32, height=24)
    plain = tuple(dataclasses.replace(m, **change) for m in scene.materials)
    path = str(tmp_path / "plain.exr")
    write_scene(path, arrays, dataclasses.replace(scene, materials=plain))
    proc = run_apply(path, "--methods", "all")
    assert proc.returncode == 3, proc.stderr
    assert "no material in the scene description scatters light" in proc.stdout
    (field,) = change
    field = "largest subsurface_radius channel" if field == "subsurface_radius" else field
    for m in (m for m in scene.materials if m.scatters):  # each names what keeps it from scattering
        assert f"material {m.name!r}: {field} = 0" in proc.stdout, proc.stdout
    assert saved_lines(proc.stdout) == []
    assert sorted(os.listdir(tmp_path)) == ["plain.exr", "plain.json"]


def test_a_pipe_or_a_device_given_as_passes_is_named_at_once(tmp_path):
    fifo = tmp_path / "passes.exr"
    os.mkfifo(fifo)
    for path in (fifo, "/dev/zero"):
        proc = run_apply(path, "--methods", "burley", "--out", tmp_path / "o.exr")
        assert proc.returncode == 2, proc.stderr
        assert "is not a regular file (a pipe or a device); expected a multilayer EXR file" in proc.stderr


def test_unknown_method_lists_the_known_ones(passes_file):
    path, _, _ = passes_file
    proc = run_apply(path, "--methods", "gaussian")
    assert proc.returncode == 2
    assert "unknown method 'gaussian'" in proc.stderr and "sta, ssss, burley" in proc.stderr


def test_scene_from_option_and_missing_sidecar(passes_file, tmp_path):
    path, _, scene = passes_file
    moved = tmp_path / "elsewhere.json"
    os.replace(os.path.splitext(path)[0] + ".json", moved)
    proc = run_apply(path, "--methods", "burley")
    assert proc.returncode == 2 and "passes.json: no scene description" in proc.stderr
    proc = run_apply(path, "--methods", "burley", "--description", moved, "--out", tmp_path / "o.exr")
    assert proc.returncode == 0, proc.stderr
    assert SceneDescription.from_json(read_layers(tmp_path / "o.exr").header["sss_lab.scene"]) == scene


def test_blender45_single_part_input(tmp_path):
    # The short names Blender 4.x writes, in one part, colour passes in half.
    arrays, scene = sphere_scene(width=32, height=24)
    short = {
        "Combined": "Combined",
        "Depth": "Depth",
        "Object Index": "IndexOB",
        "Material Index": "IndexMA",
        "Diffuse Direct": "DiffDir",
        "Diffuse Indirect": "DiffInd",
        "Diffuse Color": "DiffCol",
    }
    letters = {"Combined": "RGBA", "Depth": "Z", "Object Index": "X", "Material Index": "X"}
    channels = {}
    for name, s in short.items():
        arr = arrays[name]
        half = name.startswith("Diffuse") or name == "Combined"
        for c, letter in enumerate(letters.get(name, "RGB")):
            plane = arr if arr.ndim == 2 else arr[..., c]
            channels[f"ViewLayer.{s}.{letter}"] = plane.astype(np.float16 if half else np.float32)
    path = tmp_path / "passes45.exr"
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(str(path))
    (tmp_path / "passes45.json").write_text(scene.to_json())
    proc = run_apply(path, "--methods", "burley")
    assert proc.returncode == 0, proc.stderr
    out = read_layers(tmp_path / "passes45.sss.exr")
    assert "ViewLayer.DiffDir" in out.layers  # input layers kept under their own names
    image = out.layers["SSSLab.burley.Image"]
    plain = arrays["Material Index"] < 2
    np.testing.assert_array_equal(image[plain], arrays["Combined"][plain].astype(np.float16).astype(np.float32))


def test_skip_existing_resumes_a_chunk_and_says_what_it_kept(tmp_path):
    """A re-queued farm chunk: frames with an output are kept (not rewritten), the others done."""
    arrays, scene = sphere_scene(width=32, height=24)
    for frame in (1, 2, 3):
        write_scene(str(tmp_path / f"passes_{frame:04d}.exr"), arrays, dataclasses.replace(scene, frame=frame))
    first = run_apply(tmp_path / "passes_####.exr", "--methods", "ssss", "--frames", "2")
    assert first.returncode == 0
    kept = tmp_path / "passes_0002.sss.exr"
    stamp = kept.stat().st_mtime_ns
    proc = run_apply(tmp_path / "passes_####.exr", "--methods", "ssss", "--frames", "1-3", "--skip-existing")
    assert proc.returncode == 0, proc.stderr
    assert "apply: [2/3] frame 2: skipped, passes_0002.sss.exr exists" in proc.stdout
    assert saved_lines(proc.stdout) == [str(tmp_path / "passes_0001.sss.exr"), str(tmp_path / "passes_0003.sss.exr")]
    assert kept.stat().st_mtime_ns == stamp
    # Each frame done says how far the chunk is, with the elapsed time and the ETA.
    assert re.search(r"apply: frame 3 done in [\d.]+ s \(3/3, elapsed [\d.]+ s, ETA 0\.0 s\)", proc.stdout)
    both = run_apply(tmp_path / "passes_####.exr", "--methods", "ssss", "--skip-existing", "--overwrite")
    assert both.returncode == 2 and "not allowed with" in both.stderr
    # An output cut short (a copy interrupted, a full disk elsewhere) is not kept: applied again.
    data = kept.read_bytes()
    kept.write_bytes(data[: len(data) // 2])
    again = run_apply(tmp_path / "passes_####.exr", "--methods", "ssss", "--frames", "2", "--skip-existing")
    assert again.returncode == 0, again.stderr
    assert "does not read whole" in again.stdout and saved_lines(again.stdout) == [str(kept)]
    assert read_layers(kept).layers  # whole again


def test_param_sets_a_technique_parameter(passes_file, tmp_path):
    """--param reaches the technique: Burley at 4 samples differs from its default 32, and the
    output equals core.pipeline.apply at 4 samples."""
    from sss_lab.core.pipeline.apply import apply
    from sss_lab.core.scene.exr import Passes

    path, arrays, scene = passes_file
    out4, out32 = tmp_path / "n4.exr", tmp_path / "n32.exr"
    r4 = run_apply(path, "--methods", "burley", "--param", "n_samples=4", "--out", out4)
    r32 = run_apply(path, "--methods", "burley,ssss", "--param", "burley.n_samples=32", "--out", out32)
    assert r4.returncode == 0 and r32.returncode == 0, r4.stderr + r32.stderr
    image4 = read_layers(str(out4)).layers["SSSLab.burley.Image"]
    image32 = read_layers(str(out32)).layers["SSSLab.burley.Image"]
    assert not np.array_equal(image4, image32)
    expected = apply(Passes(arrays), scene, "burley", n_samples=4)["SSSLab.burley.Image"]
    np.testing.assert_array_equal(image4, expected)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--methods", "burley", "--param", "n_samples=0"],
            "burley.n_samples: expected an integer in [1, 1024], got 0",
        ),
        (["--methods", "burley", "--param", "taps=3"], "its parameters: n_samples, random_rotation"),
        (["--methods", "ssss,burley", "--param", "n_taps=11"], "several techniques run (ssss, burley): name one"),
        (["--methods", "ssss", "--param", "sta.power=2"], "'sta' is not among the techniques that run (ssss)"),
        (["--methods", "ssss", "--param", "n_taps=12"], "ssss.n_taps: expected one of 11, 17, 25, got 12"),
        (
            ["--methods", "burley", "--param", "n_samples=16", "--param", "n_samples=8"],
            "burley.n_samples is given twice (16 and 8); give it once",
        ),
    ],
)
def test_a_bad_param_is_one_line_naming_what_is_allowed(passes_file, args, message):
    path, _, _ = passes_file
    r = run_apply(path, *args)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], r.stderr
    assert not os.path.exists(os.path.splitext(path)[0] + ".sss.exr")


def test_what_the_scene_reader_could_not_read_is_said_once_per_run(tmp_path):
    """A material whose Subsurface Radius came from a texture carries the reader's note in the
    scene description; apply says it once, however many techniques run, and --explain shows it."""
    arrays, scene = sphere_scene(32, 24)
    note = "Subsurface Radius linked to Image Texture 'skin': not followed per pixel; (1, 0.2, 0.1) used instead"
    first = next(m for m in scene.materials if m.scatters)
    scene = dataclasses.replace(
        scene, materials=tuple(dataclasses.replace(m, notes=(note,)) if m is first else m for m in scene.materials)
    )
    path = str(tmp_path / "passes.exr")
    write_scene(path, arrays, scene)
    assert SceneDescription.from_json((tmp_path / "passes.json").read_text()) == scene
    proc = run_apply(path, "--methods", "all")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count(f"note: material {first.name!r}: {note}") == 1, proc.stdout
    proc = run_apply(path, "--methods", "burley", "--explain")
    assert proc.returncode == 0 and f"note: {note}" in proc.stdout, proc.stdout + proc.stderr


def test_a_colour_pass_saved_with_alpha_is_read_as_its_rgb(tmp_path):
    """Diffuse Direct with an A channel besides (a compositor or another program saved it so): the
    techniques read its RGB, with the same result as without the alpha."""
    arrays, scene = sphere_scene(width=32, height=24)
    plain = str(tmp_path / "plain.exr")
    write_scene(plain, arrays, scene)
    with_alpha = dict(arrays)
    direct = arrays["Diffuse Direct"]
    with_alpha["Diffuse Direct"] = np.concatenate([direct, np.full(direct.shape[:2] + (1,), 0.5, np.float32)], -1)
    alpha = str(tmp_path / "alpha.exr")
    write_scene(alpha, with_alpha, scene)
    for path in (plain, alpha):
        proc = run_apply(path, "--methods", "burley")
        assert proc.returncode == 0, proc.stderr
    a = read_layers(tmp_path / "plain.sss.exr").layers["SSSLab.burley.Image"]
    b = read_layers(tmp_path / "alpha.sss.exr").layers["SSSLab.burley.Image"]
    np.testing.assert_array_equal(a, b)


def test_a_material_index_that_is_not_a_whole_number_is_said_once_per_file(tmp_path):
    """A Material Index of 2.5 on a whole material (edited, filtered or resampled: Blender writes
    whole numbers): apply computes as before and says it in one warning per file, naming the pass
    and the number of pixels; auto's --explain says it in its plan (test_apply.py: every technique's)."""
    arrays, scene = sphere_scene(width=32, height=24)
    mi = arrays["Material Index"].copy()
    skin = mi == 2
    mi[skin] = 2.5
    path = str(tmp_path / "passes.exr")
    write_scene(path, {**arrays, "Material Index": mi}, scene)
    warning = f"warning: the Material Index pass has {int(skin.sum())} pixels that are not whole numbers (such as 2.5)"
    proc = run_apply(path, "--methods", "all")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count(warning) == 1, proc.stdout
    proc = run_apply(path, "--methods", "auto", "--explain")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count(warning) == 1, proc.stdout
