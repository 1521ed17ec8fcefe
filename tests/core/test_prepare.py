"""``core.study.prepare``: the kernels compiled ahead of the first frame (``python -m sss_lab prepare``)."""

import os
import types

import pytest

from sss_lab.core.compute import backend
from sss_lab.core.study.prepare import PrepareError, is_prepared, marker_path, prepare_kernels

#: Kernels of every path a frame takes: each technique's, the energy stage's two ("object"
#: without a bake distance, the slab's with one), the light from behind's at full resolution and
#: on the spread's reduced levels (reached only by ``core.study.prepare.FAR``'s long lengths), band by
#: band in the combined technique's call (``finish_band``) and whole in the fit's
#: (``finish_light``), ``core.pipeline.apply``'s compositing, and ``apply --methods auto``'s features
#: (``core.pipeline.auto``); STA's composite route (``sta_composite``) and its generic route.
EXPECTED = {
    "composite",
    "sta_kernel",
    "sta_composite",
    "prepare_pixels",
    "ssss_kernel",
    "burley_pack",
    "burley_kernel",
    "energy_object",
    "energy_thickness",
    "normal_cosine",
    "back_light_pixels",
    "transmit_pixels",
    "spread_band",
    "spread_pyramid",
    "blur_reduced",
    "spread_reduced_part",
    "finish_light",
    "finish_band",
    "largest_rows",
    "index_box",
    "index_window",
    "block_means",
    "blurred_change",
}


def test_prepare_runs_every_kernel_a_frame_needs_and_marks_the_cache(monkeypatch, tmp_path):
    if backend.compiled() is None:
        with pytest.raises(PrepareError, match="Numba cannot load"):
            prepare_kernels()
        assert not is_prepared()
        return
    # Numba keeps the cache it was loaded with; the marker goes to this test's folder.
    monkeypatch.setitem(backend._state, "cache_dir", str(tmp_path / "some"))
    assert not is_prepared()
    lines = []
    result = prepare_kernels(["sta"], log=lines.append)
    assert lines == ["sta: compiling or loading its kernels"]
    assert not os.path.exists(marker_path())  # only a whole preparation marks the cache
    monkeypatch.setitem(backend._state, "cache_dir", str(tmp_path / "all"))
    result = prepare_kernels()
    called = set(backend.first_call_seconds())
    assert EXPECTED <= called, sorted(EXPECTED - called)
    # What it reports is what this process called first (earlier tests may have called the rest).
    assert set(result["kernels"]) <= called and "import" not in result["kernels"]
    assert result["cache_dir"] == str(tmp_path / "all") and result["seconds"] > 0
    assert is_prepared() and os.path.dirname(marker_path()) == backend.kernel_cache_dir()
    assert os.path.dirname(backend.kernel_cache_dir()) == str(tmp_path / "all")


def test_the_command_line_prepares_and_names_a_bad_method(capsys):
    from sss_lab.addon.cli import main

    assert main(["prepare", "--methods", "nonsense"]) == 2
    assert "unknown method 'nonsense'" in capsys.readouterr().err
    code = main(["prepare", "--methods", "sta"])
    out, err = capsys.readouterr()
    if backend.compiled() is None:
        assert code == 2 and "Numba cannot load" in err
    else:
        assert code == 0, err
        assert "prepare: sta: compiling or loading its kernels" in out and "kernels ready in" in out


def test_the_marker_follows_what_numbas_cache_is_keyed_by(monkeypatch, tmp_path):
    # A reinstall unpacks the kernels anew (a new time stamp): Numba compiles again, and the
    # marker must no longer say the kernels are prepared.
    from sss_lab.core.study import prepare

    monkeypatch.setitem(backend._state, "cache_dir", str(tmp_path))
    before = marker_path()
    source = os.path.join(os.path.dirname(os.path.dirname(prepare.__file__)), "techniques", "burley", "_kernels.py")
    st = os.stat(source)
    real_stat = os.stat

    def later(path, *args, **kwargs):
        if os.path.abspath(path) == os.path.abspath(source):
            return types.SimpleNamespace(st_mtime=st.st_mtime + 60.0, st_size=st.st_size)
        return real_stat(path, *args, **kwargs)

    monkeypatch.setattr(os, "stat", later)
    assert marker_path() != before
    monkeypatch.setattr(os, "stat", real_stat)
    assert marker_path() == before


def test_ctrl_c_while_prepare_compiles_ends_as_an_interrupt(tmp_path):
    """A Ctrl-C that lands inside Numba's compiler (an empty cache, so it compiles for seconds)
    ends as every command's interrupt: exit 130 and one line, not a traceback from the compiler."""
    import os
    import signal
    import subprocess
    import sys
    import time

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.Popen(
        [sys.executable, "-m", "sss_lab", "prepare"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + 60
    while not (tmp_path / "cache").exists() and time.monotonic() < deadline:  # compiling has begun
        time.sleep(0.1)
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, (proc.returncode, err)
    assert "Traceback" not in err and err.strip().endswith("no file was finished"), err


def test_jobs_compile_in_worker_processes_and_this_process_loads_what_they_cached(capsys):
    """Two techniques in two worker processes (into the cache this process uses: earlier tests
    have filled it, so the workers load rather than compile), then loaded here as with one job."""
    if backend.compiled() is None:
        pytest.skip("Numba cannot load: nothing to compile")
    lines = []
    result = prepare_kernels(["sta", "ssss"], log=lines.append, jobs=2)
    assert sorted(line for line in lines if "worker" in line) == [
        "ssss: compiled in a worker process",
        "sta: compiled in a worker process",
    ]
    # Then this process runs both itself, in order, as prepare does with one job.
    assert [line for line in lines if "worker" not in line] == [
        "sta: compiling or loading its kernels",
        "ssss: compiling or loading its kernels",
    ]
    assert result["cache_dir"] == backend.cache_dir()
    assert {"sta_kernel", "sta_composite", "ssss_kernel"} <= set(backend.first_call_seconds())


@pytest.mark.parametrize("jobs", [0, -1, 65, 1.5, True])
def test_a_bad_number_of_jobs_is_named(jobs):
    with pytest.raises(ValueError, match=rf"jobs: expected a whole number from 1 to 64, got {jobs!r}"):
        prepare_kernels(["sta"], jobs=jobs)


def test_the_command_line_names_a_bad_jobs_value(capsys):
    from sss_lab.addon.cli import main

    assert main(["prepare", "--jobs", "0"]) == 2
    assert "--jobs 0: expected a whole number from 1 to 64" in capsys.readouterr().err
