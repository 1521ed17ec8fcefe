"""Fuzz tests with bpy (benchmarks/reliability.py, CI size, seed 1), each in a child process:
a .blend saved by Blender, cut short and with bytes inverted at seeded places, opened by
``scan`` (one clear line or opens; never a traceback, a crash or a changed file); the
reference cache damaged as crashes leave it (an image comes back, the entry is healed)."""

from benchmarks import reliability


def test_every_damaged_blend_is_handled():
    result = reliability.run_class("blend_damaged", size="ci", seed=1)
    assert result.tried >= 10
    assert result.handled == result.tried, result.failures
    assert result.kinds.get("clear error", 0) >= 3  # the text, empty and 12-byte files at least


def test_every_damaged_cache_entry_is_healed():
    result = reliability.run_class("cache_damaged", size="ci", seed=1)
    assert result.tried >= 9
    assert result.handled == result.tried, result.failures
