"""Farm progress lines (``core/base/progress.py``): elapsed time, ETA, and the one ``Saved:`` form."""

import os

import pytest

from sss_lab.core.base.progress import Progress, format_seconds, printable, saved_line


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_eta_is_the_mean_time_of_done_items_times_the_items_left():
    clock = Clock()
    p = Progress(4, clock=clock)
    assert p.position() == "[1/4]" and p.eta is None
    clock.now += 10
    assert p.finish() == "1/4, elapsed 10.0 s, ETA 30.0 s"
    clock.now += 30  # a slow second frame: the mean is 20 s
    assert p.finish() == "2/4, elapsed 40.0 s, ETA 40.0 s"
    assert p.position() == "[3/4]"


def test_skipped_items_take_no_time_and_shorten_the_eta():
    clock = Clock()
    p = Progress(4, clock=clock)
    assert p.skip() == "1/4, elapsed 0.0 s, ETA unknown"
    p.skip()
    clock.now += 5
    assert p.finish() == "3/4, elapsed 5.0 s, ETA 5.0 s"
    clock.now += 5
    assert p.finish().endswith("ETA 0.0 s")


def test_long_durations_read_as_clock_times():
    assert format_seconds(4.25) == "4.2 s"
    assert format_seconds(187) == "3:07"
    assert format_seconds(3723) == "1:02:03"
    with pytest.raises(ValueError, match="total"):
        Progress(-1)


def test_saved_line_is_blenders_form_with_an_absolute_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert saved_line("out/a b.exr") == f"Saved: '{os.path.join(tmp_path, 'out', 'a b.exr')}'"


@pytest.mark.parametrize(
    "name",
    ["skin\nSaved: '/etc/passwd'", "skin\rSaved: 'x'", "red\x1b[31m skin", "tab\there", "bell\x07", "del\x7f"],
)
def test_a_name_that_is_not_printable_cannot_forge_a_line_or_drive_the_terminal(tmp_path, name):
    """A file or material name holding a newline, a carriage return or an escape sequence: the
    Saved line stays one printable line, the characters written as escapes."""
    line = saved_line(tmp_path / name)
    assert line.isprintable() and line.startswith("Saved: '") and len(line.splitlines()) == 1
    assert printable(name) != name and printable("Skin.001 ü") == "Skin.001 ü"


def test_guarded_output_escapes_control_characters_and_forged_saved_lines():
    import io

    from sss_lab.core.base.progress import GuardedOutput, saved_line

    raw = io.StringIO()
    out = GuardedOutput(raw)
    real = saved_line("/tmp/out.exr")
    print("material 'Skin\nSaved: '/etc/passwd'\x1b[2J' read", file=out)
    print(real, file=out)
    print("a\ttab and a bell\x07", end="", file=out, flush=True)
    print("Saved: '/etc/shadow'", file=out)  # continues the line above: not a line of its own
    print("Saved: '/etc/group'", file=out)
    out.flush()
    lines = raw.getvalue().split("\n")
    assert lines[0] == "material 'Skin"
    assert lines[1] == "\\nSaved: '/etc/passwd'\\x1b[2J' read"
    assert lines[2] == real  # a line saved_line made passes unchanged
    assert lines[3] == "a\ttab and a bell\\x07Saved: '/etc/shadow'"
    assert lines[4] == "\\nSaved: '/etc/group'"
    assert [line for line in lines if line.startswith("Saved:")] == [real]
    assert "\x1b" not in raw.getvalue() and "\x07" not in raw.getvalue()
