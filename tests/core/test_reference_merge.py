"""Merging a reference rendered as N seeds × S samples (``core/study/reference.py``), without Blender.

The statistical checks use synthetic Monte Carlo images: a fixed "true" image plus independent
Gaussian noise of variance s²/n for a render of n samples, the model the merge assumes. With
128 × 128 × 3 values, an RMSE is estimated to about sqrt(1 / (2 · 49152)) ≈ 0.3 % (one standard
deviation of a Gaussian sample's RMSE); the tolerances below are 3 %, ten of those.
"""

import json
import math

import numpy as np
import pytest

from sss_lab.core.base.errors import InputError
from sss_lab.core.study import metrics
from sss_lab.core.study import reference as ref

SIZE = 128
SIGMA = 0.5  # per-sample standard deviation of the synthetic renders


def _truth():
    y, x = np.mgrid[0:SIZE, 0:SIZE] / SIZE
    rgb = np.stack([0.5 + 0.4 * x, 0.3 + 0.2 * y, 0.2 + 0.1 * x * y], axis=-1)
    return np.concatenate([rgb, np.ones((SIZE, SIZE, 1))], axis=-1).astype(np.float32)


def _render(truth, samples, seed):
    """A synthetic render: the truth plus noise of variance SIGMA²/samples (alpha noiseless)."""
    rng = np.random.default_rng(seed)
    out = truth.astype(np.float64).copy()
    out[..., :3] += rng.normal(0.0, SIGMA / math.sqrt(samples), size=truth[..., :3].shape)
    return out.astype(np.float32)


def _parts(n, s, first_seed=0):
    t = _truth()
    return [ref.ReferencePart(_render(t, s, seed), s, seed) for seed in range(first_seed, first_seed + n)]


def test_merge_is_the_sample_weighted_mean():
    a = np.full((2, 3, 4), 1.0, np.float32)
    b = np.full((2, 3, 4), 2.0, np.float32)
    merged = ref.merge_parts([ref.ReferencePart(a, 3, 0), ref.ReferencePart(b, 1, 7)])
    np.testing.assert_allclose(merged.image, 1.25, rtol=0, atol=1e-7)  # (3·1 + 1·2) / 4
    assert merged.samples == 4 and merged.seeds == (0, 7)
    assert merged.half_samples == (3, 1) and merged.half_seeds == ((0,), (7,))
    assert merged.image.dtype == np.float32


def test_halves_split_the_samples_evenly():
    a, b = ref.split_halves(_parts(8, 4))
    assert len(a) == len(b) == 4 and not {p.seed for p in a} & {p.seed for p in b}
    a, b = ref.split_halves(_parts(5, 4))
    assert sorted((len(a), len(b))) == [2, 3]
    uneven = [ref.ReferencePart(np.zeros((1, 1, 3)), n, seed) for seed, n in enumerate((8, 4, 2, 2))]
    a, b = ref.split_halves(uneven)
    assert sum(p.samples for p in a) == sum(p.samples for p in b) == 8


def test_merged_reference_matches_one_render_of_all_samples_within_its_noise_floor():
    n, s = 8, 16
    t = _truth()
    merged = ref.merge_parts(_parts(n, s))
    single = _render(t, n * s, seed=1000)
    floor = ref.noise_floor(merged)
    # The floor read from the halves equals the two-seed floor of the comparison: the metric
    # between two independent references of n·s samples.
    second = _render(t, n * s, seed=2000)
    two_seed = metrics.compare_images(second, single)["rel_rmse"]
    assert floor["rel_rmse"] == pytest.approx(two_seed, rel=0.03)
    # Merged against one render of n·s samples: both unbiased with the same variance, so their
    # difference is exactly as large as the noise floor (expected ratio 1).
    diff = metrics.compare_images(merged.image, single)["rel_rmse"]
    assert diff == pytest.approx(floor["rel_rmse"], rel=0.03)
    # And the merge has the noise of n·s samples, not of s: it is sqrt(n) closer to the truth.
    assert metrics.compare_images(merged.image, t)["rmse"] == pytest.approx(SIGMA / math.sqrt(n * s), rel=0.03)


def test_the_check_sees_a_changed_scene():
    """The match above is not automatic: parts of another image (a scene 30 % brighter) land far
    outside the floor."""
    t = _truth()
    merged = ref.merge_parts(ref.ReferencePart(p.image * 1.3, p.samples, p.seed) for p in _parts(8, 16))
    single = _render(t, 128, seed=1000)
    floor = ref.noise_floor(merged)["rel_rmse"]
    assert metrics.compare_images(merged.image, single)["rel_rmse"] > 2 * floor


def test_weights_give_the_least_noise_for_unequal_parts():
    """One part of 1 sample and seven of 16: the weighted mean has the noise of 113 samples; the
    plain mean of the eight images would have sqrt(113 (1 + 7/16) / 64) = 1.59 times more."""
    t = _truth()
    parts = [ref.ReferencePart(_render(t, 1, 0), 1, 0)] + _parts(7, 16, first_seed=1)
    merged = ref.merge_parts(parts)
    weighted = metrics.compare_images(merged.image, t)["rmse"]
    assert weighted == pytest.approx(SIGMA / math.sqrt(113), rel=0.03)
    plain = metrics.compare_images(np.mean([p.image for p in parts], axis=0), t)["rmse"]
    assert plain / weighted == pytest.approx(math.sqrt(113 * (1 + 7 / 16) / 64), rel=0.03)


def test_noise_floor_scale_for_unequal_halves():
    assert ref.halves_scale((8, 8)) == pytest.approx(1 / math.sqrt(2))
    assert ref.halves_scale((12, 4)) == pytest.approx(math.sqrt(2 * 12 * 4) / 16)
    one = ref.merge_parts(_parts(1, 16))
    assert one.halves is None and ref.noise_floor(one) is None


def test_bad_parts_are_refused_with_the_value_named():
    img = np.zeros((4, 4, 4), np.float32)
    with pytest.raises(InputError, match="same seed 3"):
        ref.merge_parts([ref.ReferencePart(img, 4, 3), ref.ReferencePart(img, 4, 3)])
    with pytest.raises(InputError, match="differs"):
        ref.merge_parts([ref.ReferencePart(img, 4, 0), ref.ReferencePart(np.zeros((4, 5, 4)), 4, 1)])
    with pytest.raises(InputError, match="samples"):
        ref.merge_parts([ref.ReferencePart(img, 0, 0)])
    with pytest.raises(InputError, match="at least one"):
        ref.merge_parts([])


def test_nan_stays_visible_in_the_merge():
    a = np.ones((2, 2, 3), np.float32)
    b = a.copy()
    b[0, 0, 0] = np.nan
    merged = ref.merge_parts([ref.ReferencePart(a, 1, 0), ref.ReferencePart(b, 1, 1)])
    assert np.isnan(merged.image[0, 0, 0]) and np.isfinite(merged.image[1:]).all()


def test_merged_file_round_trip(tmp_path):
    merged = ref.merge_parts(_parts(4, 8))
    out = tmp_path / "reference.exr"
    written = ref.write_merged(str(out), merged, {"frame": 1})
    assert written == [str(out), str(tmp_path / "reference.json")]
    back = ref.read_merged(str(out))
    np.testing.assert_array_equal(back.image, merged.image)
    np.testing.assert_array_equal(back.halves[0], merged.halves[0])
    assert back.samples == 32 and back.half_samples == (16, 16) and back.seeds == (0, 1, 2, 3)
    meta = json.loads((tmp_path / "reference.json").read_text())
    assert meta["frame"] == 1 and meta["noise_floor_whole_image"]["rel_rmse"] > 0
    with pytest.raises(FileExistsError):
        ref.write_merged(str(out), merged)


def test_parts_from_files_must_agree(tmp_path):
    from sss_lab.core.scene import exr

    paths = []
    for seed, frame in ((0, 1), (1, 2)):
        path = tmp_path / f"p{seed}.exr"
        exr.write_layers(str(path), {"ViewLayer.Combined": _render(_truth(), 4, seed)})
        (tmp_path / f"p{seed}.json").write_text(json.dumps({"samples": 4, "seed": seed, "frame": frame}))
        paths.append(str(path))
    with pytest.raises(InputError, match="differ in frame"):
        ref.read_parts(paths)
    (tmp_path / "p1.json").unlink()
    with pytest.raises(InputError, match="p1.json"):
        ref.read_part(paths[1])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"samples": "32"}, r"samples: expected an integer >= 1, got '32'"),
        ({"samples": 0}, r"samples: expected an integer >= 1"),
        ({"seeds": [0, -1]}, r"seeds: expected a list of integers >= 0"),
        ({"half_samples": [16]}, r"half_samples: expected null or two integers >= 1"),
        ({"half_seeds": [[0, 1], "2"]}, r"half_seeds: expected null or two lists"),
        ({"frame": 1.5}, r"frame: expected an integer"),
        ({"fingerprint": 7}, r"fingerprint: expected a string"),
        ({"seconds": -1}, r"seconds: expected a finite number >= 0"),
    ],
)
def test_a_merged_references_json_is_checked_field_by_field(tmp_path, change, message):
    """The JSON beside a merged reference, hand-edited or damaged: one line naming the file and
    the field, as a scene description's checks do, never a traceback or a silent wrong value."""
    out = tmp_path / "reference.exr"
    ref.write_merged(str(out), ref.merge_parts(_parts(4, 8)), {"frame": 1})
    meta_path = tmp_path / "reference.json"
    meta = json.loads(meta_path.read_text())
    meta.update(change)
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(InputError, match=r"reference\.json: " + message):
        ref.read_merged(str(out))


def test_a_damaged_json_or_a_part_of_another_size_is_refused(tmp_path):
    from sss_lab.core.scene import exr

    out = tmp_path / "reference.exr"
    ref.write_merged(str(out), ref.merge_parts(_parts(4, 8)), {"frame": 1})
    (tmp_path / "reference.json").write_text('{"samples": 32,')
    with pytest.raises(InputError, match="reference.json: not readable JSON"):
        ref.read_merged(str(out))
    part = tmp_path / "p0.exr"
    image = _render(_truth(), 4, 0)
    exr.write_layers(str(part), {"ViewLayer.Combined": image})
    h, w = image.shape[:2]
    (tmp_path / "p0.json").write_text(json.dumps({"samples": 4, "seed": 0, "resolution": [w + 1, h]}))
    with pytest.raises(InputError, match=f"p0.exr is {w}x{h} pixels but p0.json says {w + 1}x{h}"):
        ref.read_part(str(part))


def _part_folder(folder, seeds=(1, 2), fingerprint="abc"):
    from sss_lab.core.scene import exr

    folder.mkdir()
    for seed in seeds:
        exr.write_layers(
            str(folder / f"reference_seed_{seed:05d}.exr"), {"ViewLayer.Combined": _render(_truth(), 4, seed)}
        )
        meta = {"samples": 4, "seed": seed, "frame": 1}
        if fingerprint:
            meta["fingerprint"] = fingerprint
        (folder / f"reference_seed_{seed:05d}.json").write_text(json.dumps(meta))
    return folder


def _contents(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.mark.parametrize(
    "out",
    [
        "alias/reference_seed_00001.exr",  # a part, through a link to its folder
        "parts/reference_seed_00001.merged",  # its JSON would be part 1's
        "alias/reference_seed_00002.exr",
        "parts/./reference_seed_00002.json.exr",  # a name whose JSON is not a part's: allowed
    ],
)
def test_merge_never_writes_over_a_part_or_its_json_however_spelled(tmp_path, out, capsys):
    from sss_lab.addon.cli import main

    parts = _part_folder(tmp_path / "parts")
    (tmp_path / "alias").symlink_to(parts, target_is_directory=True)
    before = _contents(parts)
    code = main(["merge-reference", str(parts), "--out", str(tmp_path / out), "--overwrite"])
    if out.endswith(".json.exr"):
        assert code == 0
        return
    assert code == 2
    assert "is one of the parts or a part's JSON; refusing to overwrite it" in capsys.readouterr().err
    assert _contents(parts) == before


def test_merge_names_a_folder_output_and_refuses_parts_it_cannot_tell_apart(tmp_path, capsys):
    from sss_lab.addon.cli import main

    parts = _part_folder(tmp_path / "parts")
    (tmp_path / "x").mkdir()
    assert main(["merge-reference", str(parts), "--out", str(tmp_path / "x")]) == 2
    assert "is a folder; expected the merged reference's EXR file name" in capsys.readouterr().err
    bare = _part_folder(tmp_path / "bare", fingerprint=None)
    assert main(["merge-reference", str(bare), "--out", str(tmp_path / "m.exr")]) == 2
    err = capsys.readouterr().err
    assert "reference_seed_00001.exr, reference_seed_00002.exr: no scene fingerprint" in err
    assert not (tmp_path / "m.exr").exists()
    single = _part_folder(tmp_path / "single", seeds=(3,), fingerprint=None)  # one part: nothing to mix up
    assert main(["merge-reference", str(single), "--out", str(tmp_path / "one.exr")]) == 0


@pytest.mark.parametrize(
    ("change", "message"),
    [
        # The samples against what the JSON records of the parts, and against the EXR's own record.
        ({"samples": 1_000_000_000}, r"samples 1000000000 disagrees with its part_samples 8 \+ 8 \+ 8 \+ 8 = 32"),
        ({"samples": 33, "part_samples": None}, r"samples 33 disagrees with its half_samples 16 \+ 16 = 32"),
        (
            {"samples": 64, "part_samples": [16, 16, 16, 16], "half_samples": [32, 32]},
            r"samples 64 disagrees with reference\.exr's own record of 32 samples",
        ),
        ({"part_samples": [8, 8, 16]}, r"part_samples holds 3 counts for 4 seeds"),
        # Older files (no part_samples, no halves): the EXR's record still holds.
        ({"samples": 40, "part_samples": None, "half_samples": None}, r"own record of 32 samples"),
        ({"seeds": [0, 1, 2, 5]}, r"seeds \[0, 1, 2, 5\] disagree with reference\.exr's own record of seeds"),
        ({"seeds": [0, 1, 1, 2]}, r"seeds: expected distinct seeds"),
        ({"half_seeds": [[0, 1], [1, 3]]}, r"half_seeds \[\[0, 1\], \[1, 3\]\] are not the seeds"),
        ({"parts": ["a.exr"]}, r"parts names 1 file\(s\) for 4 seeds"),
        # The size the JSON gives against the EXR's.
        (
            {"resolution": [32, 32]},
            rf"reference\.exr is {SIZE}x{SIZE} pixels but reference\.json says 32x32 \(its resolution\)",
        ),
    ],
)
def test_a_merged_references_json_must_agree_with_itself_and_its_exr(tmp_path, change, message):
    """A hand-edited JSON whose samples, seeds or size are not those of the merge beside it: one
    line naming the file and the field, never a reference weighted as something it is not."""
    out = tmp_path / "reference.exr"
    ref.write_merged(str(out), ref.merge_parts(_parts(4, 8)), {"frame": 1, "resolution": [SIZE, SIZE]})
    meta_path = tmp_path / "reference.json"
    meta = json.loads(meta_path.read_text())
    assert meta["part_samples"] == [8, 8, 8, 8]
    meta.update(change)
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(InputError, match=message):
        ref.read_merged(str(out))


def test_a_file_that_is_not_a_merged_reference_is_refused(tmp_path):
    """A passes file (its Combined layer and its scene description beside it), or any EXR not
    written by merge-reference, is no merged reference of 0 samples: refused, naming it."""
    from sss_lab.core.scene import exr

    passes = tmp_path / "passes_0001.exr"
    exr.write_layers(str(passes), {"ViewLayer.Combined": _truth(), "ViewLayer.Depth": _truth()[..., :1]})
    (tmp_path / "passes_0001.json").write_text(json.dumps({"version": 1, "frame": 1, "camera": {}, "materials": []}))
    with pytest.raises(InputError, match=r"passes_0001\.exr: not a merged reference \(passes_0001\.json is the scene"):
        ref.read_merged(str(passes))
    (tmp_path / "passes_0001.json").unlink()
    with pytest.raises(InputError, match=r"passes_0001\.exr: not a merged reference \(its header has no sss_lab_"):
        ref.read_merged(str(passes))
    # A merged reference whose JSON lost its samples, and one without JSON but with the EXR's record
    # (one part: no halves, whose counts only the JSON gives).
    out = tmp_path / "reference.exr"
    ref.write_merged(str(out), ref.merge_parts(_parts(1, 8, first_seed=3)))
    meta = json.loads((tmp_path / "reference.json").read_text())
    (tmp_path / "reference.json").write_text(json.dumps({k: v for k, v in meta.items() if k != "samples"}))
    with pytest.raises(InputError, match=r"reference\.exr: not a merged reference \(reference\.json has no 'samples'"):
        ref.read_merged(str(out))
    (tmp_path / "reference.json").unlink()
    back = ref.read_merged(str(out))
    assert back.samples == 8 and back.seeds == (3,) and back.halves is None
