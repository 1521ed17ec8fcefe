"""Fuzz test: a .blend saved by Blender, cut short and with bytes inverted at seeded places,
opened by ``scan`` in a child process (benchmarks/reliability.py, CI size, seed 1): each is one
clear line or opens; none is a traceback, a crash or a changed file."""

from benchmarks import reliability


def test_every_damaged_blend_is_handled():
    result = reliability.run_class("blend_damaged", size="ci", seed=1)
    assert result.tried >= 10
    assert result.handled == result.tried, result.failures
    assert result.kinds.get("clear error", 0) >= 3  # the text, empty and 12-byte files at least
