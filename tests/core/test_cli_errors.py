"""The command line's error contract: an error SSS Lab raises on purpose, a bad file, a full or
read-only disk and Ctrl-C each end as one line on stderr and a non-zero exit; ``--debug``
adds the traceback; no temporary file is left. Run in-process on the NumPy-only command."""

import errno
import os
import shutil

import OpenEXR
import pytest

from sss_lab.addon import cli
from sss_lab.core.base import errors
from sss_lab.core.pipeline import sequence
from sss_lab.core.study.synthetic import sphere_scene, write_scene


@pytest.fixture
def passes(tmp_path):
    arrays, scene = sphere_scene(width=24, height=16)
    path = str(tmp_path / "passes.exr")
    write_scene(path, arrays, scene)
    return path


def _run(capsys, *argv):
    code = cli.main(list(map(str, argv)))
    out, err = capsys.readouterr()
    return code, out, err


def _leftovers(folder):
    return [n for n in os.listdir(folder) if n.endswith(".tmp")]


def test_a_damaged_input_is_one_line(passes, tmp_path, capsys):
    data = open(passes, "rb").read()
    (tmp_path / "cut.exr").write_bytes(data[:-1])
    (tmp_path / "cut.json").write_bytes(open(sequence.sidecar_path(passes), "rb").read())
    code, _, err = _run(capsys, "apply", tmp_path / "cut.exr", "--methods", "burley")
    assert code == 2  # a bad input (the rule: 2 bad input, 1 a failed write or run)
    lines = err.strip().splitlines()
    assert lines[0].startswith("sss_lab apply: error: ") and "cut.exr" in lines[0] and "truncated" in lines[0]
    assert "Traceback" not in err and "Warning:" not in err  # OpenEXR's own warnings are folded in
    assert not os.path.exists(tmp_path / "cut.sss.exr")


def test_an_error_outside_the_frame_loop_is_one_line_and_debug_adds_the_traceback(passes, capsys):
    code, _, err = _run(capsys, "apply", passes, "--methods", "burley", "--frames", "1-100000000")
    assert code == 2 and err.count("\n") == 1 and "more than 100000 frames" in err
    code, _, err = _run(capsys, "--debug", "apply", passes, "--methods", "burley", "--frames", "1-100000000")
    assert code == 2 and "Traceback" in err and err.strip().endswith("every existing file")
    code, _, err = _run(capsys, "apply", passes, "--methods", "burley", "--frames", "1-100000000", "--debug")
    assert code == 2 and "Traceback" in err


def test_a_full_disk_is_one_line_and_leaves_no_temporary_file(passes, tmp_path, capsys, monkeypatch):
    # OpenEXR reports a write that ran out of space as a RuntimeError; the free space says why.
    class FullDisk:
        def __init__(self, *args, **kwargs):
            pass

        def write(self, filename):
            with open(filename, "wb") as fh:
                fh.write(b"the first bytes")
            raise RuntimeError("Cannot write image file: error writing chunk")

    real_file = OpenEXR.File
    monkeypatch.setattr(
        OpenEXR, "File", lambda *a, **k: real_file(*a, **k) if a and isinstance(a[0], str) else FullDisk()
    )
    monkeypatch.setattr(shutil, "disk_usage", lambda folder: shutil._ntuple_diskusage(1 << 30, 1 << 30, 0))
    code, out, err = _run(capsys, "apply", passes, "--methods", "burley")
    assert code == 1 and "Saved" not in out
    (line,) = [x for x in err.splitlines() if "error:" in x]
    assert "passes.sss.exr: No space left on device; the disk is full" in line
    assert _leftovers(tmp_path) == [] and not os.path.exists(tmp_path / "passes.sss.exr")


def test_a_read_only_folder_is_one_line(passes, tmp_path, capsys, monkeypatch):
    import tempfile

    def refuse(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system", kwargs.get("dir"))

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    code, _, err = _run(capsys, "apply", passes, "--methods", "burley")
    assert code == 1
    assert "passes.sss.exr: Read-only file system; the file system is read-only: write elsewhere with --out" in err
    assert "Traceback" not in err


def test_ctrl_c_exits_130_with_one_line(passes, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(sequence, "apply_file", interrupted)
    code, _, err = _run(capsys, "apply", passes, "--methods", "burley")
    assert code == cli.EXIT_INTERRUPTED == 130
    assert err.strip().startswith("sss_lab apply: interrupted (Ctrl-C); ") and err.count("\n") == 1


def test_a_bug_keeps_its_traceback(passes, capsys, monkeypatch):
    def bug(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(cli, "parse_methods", bug)
    with pytest.raises(ZeroDivisionError):
        cli.main(["apply", passes, "--methods", "burley"])


def test_after_ctrl_c_nothing_is_published_and_the_job_is_not_a_success(tmp_path):
    # Blender swallows a KeyboardInterrupt raised inside its render callback and may finish the
    # job on a cut-short result: from the interrupt on, no output is moved into place, and a
    # guarded block that returns normally still ends as interrupted.
    import signal

    from sss_lab.addon.interrupt import interrupt_guard
    from sss_lab.core.base import files

    target = tmp_path / "late.exr"
    with pytest.raises(KeyboardInterrupt):
        with interrupt_guard("test", grace=60.0):
            try:
                signal.raise_signal(signal.SIGINT)  # what Ctrl-C does
            except KeyboardInterrupt:
                pass  # swallowed, as Blender's callback does
            deadline = 0
            while not files.INTERRUPTED.is_set() and deadline < 500:  # the watcher thread sets it
                import time

                time.sleep(0.01)
                deadline += 1
            with pytest.raises(KeyboardInterrupt):
                files.write_text(str(target), "finished after the interrupt")
    assert not target.exists() and os.listdir(tmp_path) == []
    files.INTERRUPTED.clear()


@pytest.mark.parametrize(
    ("extra", "flag"), [(["--out", ""], "--out"), (["--out", "  "], "--out"), (["--frames", ""], "--frames")]
)
def test_an_empty_path_or_frame_list_is_an_error_not_the_default(passes, capsys, extra, flag):
    """``--out ''`` (a script's unset variable) silently wrote the default output beside the input,
    and ``--frames ''`` applied every frame: both are one line naming the flag, exit 2, nothing
    written."""
    folder = os.path.dirname(passes)
    before = sorted(os.listdir(folder))
    code, _, err = _run(capsys, "apply", passes, "--methods", "burley", *extra)
    assert code == 2 and f"{flag}: empty" in err and err.count("\n") == 1
    assert sorted(os.listdir(folder)) == before


# One exit rule for every way a command stops on an error: 2 bad input, 1 a failed write. The
# errors: what each kind of fault raises (a path naming a folder, nothing, or an existing output;
# a bad value; a missing pass; a full or read-only disk, no permission).
EXIT_RULE = [
    (IsADirectoryError(errno.EISDIR, "Is a directory", "x"), 2),
    (NotADirectoryError(errno.ENOTDIR, "Not a directory", "x"), 2),
    (FileNotFoundError(errno.ENOENT, "No such file", "x"), 2),
    (FileExistsError(errno.EEXIST, "exists", "x"), 2),
    (ValueError("bad value"), 2),
    (KeyError("no such pass"), 2),
    (OSError(errno.ENOSPC, "No space left on device", "x"), 1),
    (PermissionError(errno.EACCES, "Permission denied", "x"), 1),
    (OSError(errno.EROFS, "Read-only file system", "x"), 1),
]


@pytest.mark.parametrize("exc,code", EXIT_RULE, ids=[type(e).__name__ + str(c) for e, c in EXIT_RULE])
def test_the_exit_rule_is_one_for_the_command_and_for_each_frame(passes, capsys, monkeypatch, exc, code):
    """The same error gives the same status whether it stops the command (raised before the frames)
    or fails a frame of apply (raised while one is applied)."""
    assert errors.is_bad_input(exc) == (code == 2)

    def fail(*args, **kwargs):
        raise exc

    with monkeypatch.context() as m:
        m.setattr(sequence, "apply_file", fail)
        in_frame, _, err = _run(capsys, "apply", passes, "--methods", "burley")
    assert in_frame == code and "Traceback" not in err, err
    if isinstance(exc, KeyError):
        return  # the command's own handler takes what a command raises on purpose; a KeyError there is a bug
    with monkeypatch.context() as m:
        m.setattr(cli, "parse_methods", fail)
        whole, _, err = _run(capsys, "apply", passes, "--methods", "burley")
    assert whole == code and "Traceback" not in err, err
