"""The reference rendered in parts by seed (``blender/reference.py``) and merged
(``core/study/reference.py``) matches one render of all its samples within the noise floor.

Small: ``head_frontlit`` (the demo scene) at 48 × 48, 4 parts of 32
samples against one render of 128 samples, metric as in the comparison (relative RMSE over the
subsurface pixels, 2 × 2 box).
"""

import json
import os

import numpy as np
import pytest

from sss_lab.blender.samples import load_sample_scenes
from sss_lab.core.pipeline import sequence as core_sequence
from sss_lab.core.scene import exr
from sss_lab.core.study import metrics
from sss_lab.core.study import reference as ref

SIZE = (48, 48)
TASKS, SAMPLES = 4, 32


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Parts, one single render of all the samples, and the no-SSS image, rendered once."""
    import bpy

    from sss_lab.blender.reference import render_reference_parts
    from sss_lab.blender.render_passes import render_passes

    work = tmp_path_factory.mktemp("seed_split")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    load_sample_scenes().build("head_frontlit", str(work / "head.blend"))
    scene = bpy.context.scene
    lines = []
    parts = render_reference_parts(
        scene, str(work / "parts"), seeds=range(1, TASKS + 1), samples=SAMPLES, resolution=SIZE, log=lines.append
    )
    single, _ = render_reference_parts(
        scene, str(work / "single"), seeds=[1000], samples=TASKS * SAMPLES, resolution=SIZE, log=None
    )
    passes, _ = render_passes(
        scene, str(work / "passes"), techniques=["ssss"], samples=TASKS * SAMPLES, resolution=SIZE, log=None
    )
    return {"work": work, "parts": parts, "single": single, "passes": passes, "lines": lines}


def _mask(passes_path):
    desc = core_sequence.load_scene(passes_path)
    index = np.rint(np.nan_to_num(exr.read_passes(passes_path)["Material Index"])).astype(np.int64)
    return np.isin(index[..., 0] if index.ndim == 3 else index, [m.index for m in desc.materials if m.scatters])


def test_parts_are_written_with_what_the_merge_checks(rendered):
    exrs = [p for p in rendered["parts"] if p.endswith(".exr")]
    assert [os.path.basename(p) for p in exrs] == [f"reference_seed_{s:05d}.exr" for s in range(1, TASKS + 1)]
    meta = json.loads(open(ref.sidecar(exrs[0]), encoding="utf-8").read())
    assert meta["samples"] == SAMPLES and meta["seed"] == 1 and meta["resolution"] == list(SIZE)
    assert meta["frame"] == 1 and len(meta["fingerprint"]) == 64
    saved = [line for line in rendered["lines"] if line.startswith("Saved:")]
    assert saved[0] == f"Saved: '{exrs[0]}'" and len(saved) == 2 * TASKS
    assert any("ETA" in line for line in rendered["lines"])


def test_merged_parts_match_one_render_of_all_the_samples_within_the_noise_floor(rendered):
    parts, _ = ref.read_parts([p for p in rendered["parts"] if p.endswith(".exr")])
    merged = ref.merge_parts(parts)
    assert merged.samples == TASKS * SAMPLES
    single = exr.read_passes(rendered["single"])["Combined"]
    mask = _mask(rendered["passes"])
    assert mask.sum() > 200  # the head covers enough pixels for the metric to mean something
    floor = ref.noise_floor(merged, mask, box=2)["rel_rmse"]
    diff = metrics.compare_images(merged.image, single, mask, box=2)["rel_rmse"]
    # Both are unbiased estimates of the same image with about the same variance, so the
    # expected ratio is 1 (core/study/reference.py); 1.5 leaves room for the sampling fluctuation of
    # two RMSEs over a few hundred downsampled pixels and Cycles' heavier-than-Gaussian tails.
    print(f"merged vs single {diff:.4f}, noise floor from the halves {floor:.4f}")
    assert diff < 1.5 * floor, (diff, floor)
    # Each part alone is far noisier than the merge: the merge does add the samples up.
    one = metrics.compare_images(parts[0].image, single, mask, box=2)["rel_rmse"]
    assert one > 1.5 * diff
    # And the check can fail: the scene rendered without subsurface scattering (the passes'
    # Combined) is far outside the floor.
    no_sss = exr.read_passes(rendered["passes"])["Combined"]
    assert metrics.compare_images(no_sss, single, mask, box=2)["rel_rmse"] > 2 * floor


def test_skip_existing_keeps_finished_parts_and_refuses_different_ones(rendered):
    import bpy

    from sss_lab.blender.reference import render_reference_parts
    from sss_lab.core.base.errors import InputError

    bpy.ops.wm.open_mainfile(filepath=str(rendered["work"] / "head.blend"), load_ui=False)
    scene = bpy.context.scene
    folder = str(rendered["work"] / "parts")
    first = os.path.join(folder, "reference_seed_00001.exr")
    before = os.stat(first).st_mtime_ns
    lines = []
    written = render_reference_parts(
        scene, folder, seeds=[1], samples=SAMPLES, resolution=SIZE, skip_existing=True, log=lines.append
    )
    assert written == [] and os.stat(first).st_mtime_ns == before
    assert any("seed 1: skipped" in line for line in lines)
    with pytest.raises(InputError, match="samples 32 there, 8 asked"):
        render_reference_parts(scene, folder, seeds=[1], samples=8, resolution=SIZE, skip_existing=True, log=None)
    with pytest.raises(FileExistsError, match="--skip-existing"):
        render_reference_parts(scene, folder, seeds=[1], samples=SAMPLES, resolution=SIZE, log=None)


def _cut(path):
    with open(path, "r+b") as fh:
        fh.truncate(os.path.getsize(path) // 2)


def _rewrite(path, **values):
    meta = json.loads(open(path, encoding="utf-8").read())
    meta.update(values)
    open(path, "w", encoding="utf-8").write(json.dumps(meta))


#: What a killed task, a full disk or a copy leaves of a part: each is no finished part of the job.
DAMAGE = {
    "EXR cut to half": lambda exr_path, meta: _cut(exr_path),
    "JSON missing": lambda exr_path, meta: os.remove(meta),
    "JSON cut short": lambda exr_path, meta: open(meta, "w").write('{"samples": 3'),
    "EXR missing": lambda exr_path, meta: os.remove(exr_path),
    "JSON of another seed": lambda exr_path, meta: _rewrite(meta, seed=9),
    "EXR of another size": lambda exr_path, meta: (
        os.remove(exr_path),
        exr.write_layers(exr_path, {"ViewLayer.Combined": np.zeros((16, 16, 4), np.float32)}),
    ),
}


def test_skip_existing_renders_again_every_part_that_is_not_finished(rendered, tmp_path):
    """--skip-existing keeps only whole parts of the same job: a part cut short, missing a file,
    or whose EXR and JSON disagree is rendered again with a line saying so, never kept (the merge
    would then fail on it, or weigh a wrong image)."""
    import shutil

    import bpy

    from sss_lab.blender.reference import render_reference_parts

    bpy.ops.wm.open_mainfile(filepath=str(rendered["work"] / "head.blend"), load_ui=False)
    scene = bpy.context.scene
    damages = sorted(DAMAGE)
    for first in range(0, len(damages), TASKS - 1):
        batch = damages[first : first + TASKS - 1]
        folder = tmp_path / f"parts{first}"
        shutil.copytree(rendered["work"] / "parts", folder)
        kept = os.path.join(folder, "reference_seed_00001.exr")
        before = os.stat(kept).st_mtime_ns
        for seed, damage in enumerate(batch, start=2):
            path = os.path.join(folder, f"reference_seed_{seed:05d}.exr")
            DAMAGE[damage](path, ref.sidecar(path))
        lines = []
        written = render_reference_parts(
            scene,
            str(folder),
            seeds=range(1, TASKS + 1),
            samples=SAMPLES,
            resolution=SIZE,
            skip_existing=True,
            log=lines.append,
        )
        again = list(range(2, len(batch) + 2))
        assert [p for p in written if p.endswith(".exr")] == [
            os.path.join(folder, f"reference_seed_{s:05d}.exr") for s in again
        ], batch
        assert os.stat(kept).st_mtime_ns == before and any("seed 1: skipped" in line for line in lines)
        for seed in again:
            said = [line for line in lines if line.startswith(f"seed {seed}: reference_seed_{seed:05d}.exr is not")]
            assert said and said[0].endswith("rendering it again"), (batch, lines)
        parts, _ = ref.read_parts(sorted(str(p) for p in folder.glob("*.exr")))  # whole again
        assert [p.seed for p in parts] == list(range(1, TASKS + 1))


def test_compare_uses_the_merged_reference_and_its_halves(rendered, capsys):
    """merge-reference (the command) then compare --reference: the report's reference is the
    merge, its noise floor comes from the halves, and a reference of another frame or another
    state of the scene is refused."""
    import bpy

    from sss_lab.addon import cli
    from sss_lab.blender.compare import CompareSettings, compare
    from sss_lab.core.base.errors import InputError

    merged_path = rendered["work"] / "merged" / "reference.exr"
    assert cli.main(["merge-reference", str(rendered["work"] / "parts"), "--out", str(merged_path)]) == 0
    out = capsys.readouterr().out
    assert f"Saved: '{merged_path}'" in out and f"{TASKS} part(s)" in out
    bpy.ops.wm.open_mainfile(filepath=str(rendered["work"] / "head.blend"), load_ui=False)
    scene = bpy.context.scene
    settings = CompareSettings(
        resolution=SIZE,
        pass_samples=2,
        peer_samples=(16,),
        techniques=("ssss",),
        reference_file=str(merged_path),
        eevee=False,
    )
    data = compare(scene, str(rendered["work"] / "report"), settings, log=lambda _line: None)
    assert data["settings"]["reference_samples"] == TASKS * SAMPLES
    assert data["settings"]["reference_seeds"] == list(range(1, TASKS + 1))
    assert data["noise_floor"]["halves"]["samples"] == [TASKS * SAMPLES // 2] * 2
    assert not any("Christensen-Burley" in e["name"] for e in data["entries"])  # as costly as the reference
    scene.frame_set(2)
    with pytest.raises(InputError, match="frame 1; the comparison is of frame 2"):
        compare(scene, str(rendered["work"] / "report2"), settings, log=None)
    scene.frame_set(1)
    next(o for o in scene.objects if o.type == "LIGHT").data.energy *= 2
    with pytest.raises(InputError, match="another state of the scene"):
        compare(scene, str(rendered["work"] / "report3"), settings, log=None)
