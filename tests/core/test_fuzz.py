"""Fuzz tests: generated corpora of damaged inputs (benchmarks/reliability.py) at CI size,
seed 1. Every case must be handled: one clear error naming the file, or a complete result;
never a traceback, a silently missing layer or technique, a changed input or a leftover
temporary file. ``python -m benchmarks.reliability`` runs larger held-out corpora."""

import pytest

from benchmarks import reliability

#: Classes and the fewest cases each must try (so that a generator that yields nothing fails).
CLASSES = {
    "exr_truncated": 20,
    "exr_flipped": 20,
    "exr_structure": 30,
    "json_damaged": 60,
    "scale_extremes": 10,
    "output_targets": 10,
    "frame_ranges": 7,
    "disk_faults": 11,
}


@pytest.mark.parametrize("name", sorted(CLASSES))
def test_every_generated_fault_is_handled(name):
    result = reliability.run_class(name, size="ci", seed=1)
    assert result.tried >= CLASSES[name]
    assert result.handled == result.tried, result.failures


def test_the_harness_tells_a_silent_loss_from_a_clear_error(tmp_path):
    # Guards the classification the tests above rely on: a file whose last part OpenEXR drops
    # must be an error; a result that lacks a layer the input had must count as not handled.
    path, arrays, _ = reliability.base_files(str(tmp_path))
    expected = [f"ViewLayer.{name}" for name in arrays] + ["ViewLayer.Not There"]
    outcome = reliability.apply_outcome(path, expected)
    assert not outcome.handled and outcome.kind.startswith("silent loss")
    assert reliability.apply_outcome(path, expected[:-1]).kind == "complete result"
