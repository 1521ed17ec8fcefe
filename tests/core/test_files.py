"""Temporaries left by a killed process (SIGKILL, a power cut) are removed by the next writer of
the same output, and only those: never a live process's, never another host's."""

from __future__ import annotations

import os
import socket
import subprocess
import sys

from sss_lab.core.base import files


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def _host() -> str:
    return "".join(c if c.isalnum() or c == "-" else "-" for c in socket.gethostname())[:64] or "host"


def test_the_next_writer_removes_a_killed_writers_temporary_and_nothing_else(tmp_path):
    out = tmp_path / "frame.exr"
    dead = tmp_path / f".frame.exr.{_host()}-{_dead_pid()}.abc123.exr"
    live = tmp_path / f".frame.exr.{_host()}-{os.getppid()}.def456.exr"  # the test runner's parent
    other_host = tmp_path / f".frame.exr.elsewhere-{_dead_pid()}.ghi789.exr"
    other_file = tmp_path / f".other.exr.{_host()}-{_dead_pid()}.jkl000.exr"
    for p in (dead, live, other_host, other_file):
        p.write_bytes(b"partial")
    files.write_bytes(str(out), b"whole")
    assert out.read_bytes() == b"whole"
    assert not dead.exists()
    assert live.exists() and other_host.exists() and other_file.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, live.name, other_host.name, other_file.name])


def test_a_temporary_name_carries_host_and_process(tmp_path):
    with files.temporary_beside(str(tmp_path / "x.exr"), suffix=".exr") as tmp:
        assert os.path.basename(tmp).startswith(f".x.exr.{_host()}-{os.getpid()}.")


def test_a_killed_runs_working_folder_goes_with_the_next_run(tmp_path, monkeypatch):
    monkeypatch.setattr(files.tempfile, "tempdir", str(tmp_path))
    stale = tmp_path / f"sss_lab_fit_{_host()}-{_dead_pid()}_k2j3"
    stale.mkdir()
    (stale / "cycles.exr").write_bytes(b"x")
    live = tmp_path / f"sss_lab_fit_{_host()}-{os.getppid()}_k2j4"
    live.mkdir()
    with files.temporary_folder("sss_lab_fit_") as folder:
        assert os.path.isdir(folder) and os.path.basename(folder).startswith(f"sss_lab_fit_{_host()}-{os.getpid()}_")
        assert not stale.exists() and live.exists()
    assert not os.path.exists(folder)


def test_an_interrupt_that_ends_the_process_at_once_removes_every_temporary(tmp_path):
    """What the forced exit after Ctrl-C, SIGTERM or SIGHUP calls (``remove_pending_temporaries``,
    while Blender is busy and no ``finally`` will run) removes both kinds of temporaries: a
    file beside its output and a working folder with what it holds."""
    with files.temporary_beside(str(tmp_path / "out.exr")) as tmp_file:
        with open(tmp_file, "w") as fh:
            fh.write("cut short")
        with files.temporary_folder("sss_lab_test_") as folder:
            with open(os.path.join(folder, "reference.exr"), "w") as fh:
                fh.write("half a render")
            os.makedirs(os.path.join(folder, "sub"))
            assert {tmp_file, folder} <= set(files.pending_temporaries())
            files.remove_pending_temporaries()
            assert not os.path.exists(tmp_file) and not os.path.exists(folder)
            assert files.pending_temporaries() == []
    assert not os.path.exists(tmp_path / "out.exr")
