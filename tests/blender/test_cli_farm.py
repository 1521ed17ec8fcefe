"""The farm options of the Blender commands: ``render --skip-existing``, ``--threads`` and
``--device``, through ``python -m sss_lab``'s entry point (the same one ``blender --command
sss_lab`` calls). Small: the demo scene at 32 × 24, 2 samples."""

import os
import shutil

import pytest

from sss_lab.addon import cli
from sss_lab.blender.samples import load_sample_scenes

SAMPLES = "2"


@pytest.fixture(scope="module")
def blend(tmp_path_factory):
    path = tmp_path_factory.mktemp("farm_cli") / "head.blend"
    load_sample_scenes().build("head_frontlit", str(path))
    return path


def _render(blend, out, *extra):
    return cli.main(
        [
            "render",
            str(blend),
            "--out",
            str(out),
            "--frames",
            "1-3",
            "--pass-samples",
            SAMPLES,
            "--resolution",
            "32x24",
            "--methods",
            "ssss",
            *extra,
        ]
    )


def test_skip_existing_renders_only_the_missing_frames_and_says_which(blend, tmp_path, capsys):
    assert _render(blend, tmp_path, "--frames", "2") == 0
    kept = tmp_path / "passes_0002.exr"
    stamp = kept.stat().st_mtime_ns
    capsys.readouterr()
    assert _render(blend, tmp_path) == 2  # without an option it refuses, naming both ways out
    assert "--overwrite" in capsys.readouterr().err
    assert _render(blend, tmp_path, "--skip-existing") == 0
    out = capsys.readouterr().out
    assert "render: [1/3] frame 2: skipped, passes_0002.exr exists" in out  # kept frames are counted first
    assert f"Saved: '{tmp_path / 'passes_0001.exr'}'" in out and f"Saved: '{tmp_path / 'passes_0003.exr'}'" in out
    assert "passes_0002" not in out.replace("passes_0002.exr exists", "")
    assert "render: frame 3 done in" in out and "(3/3, elapsed" in out and "ETA 0.0 s)" in out
    assert kept.stat().st_mtime_ns == stamp
    # A frame whose scene description is missing (a task killed between the two files) is redone.
    os.remove(tmp_path / "passes_0003.json")
    assert _render(blend, tmp_path, "--skip-existing") == 0
    out = capsys.readouterr().out
    assert "[1/3] frame 1: skipped" in out and "[2/3] frame 2: skipped" in out and "[3/3] frame 3: rendering" in out
    # Frames rendered for other techniques are not passed off as this request's.
    assert _render(blend, tmp_path, "--skip-existing", "--methods", "burley") == 2
    assert "holds no passes for burley" in capsys.readouterr().err
    # Nor frames of another size or seed.
    assert _render(blend, tmp_path, "--skip-existing", "--resolution", "16x12") == 2
    assert "32x24 pixels, not 16x12" in capsys.readouterr().err
    assert _render(blend, tmp_path, "--skip-existing", "--seed", "5") == 2
    assert "seed 0, not 5" in capsys.readouterr().err
    # Nor frames of another .blend file (the same scene name, "Scene", in both).
    other = tmp_path.parent / f"{tmp_path.name}_other.blend"
    shutil.copy(blend, other)
    assert _render(other, tmp_path, "--skip-existing") == 2
    assert f"from 'head.blend', not '{other.name}'" in capsys.readouterr().err


def test_skip_existing_renders_a_cut_short_frame_again(blend, tmp_path, capsys):
    """A passes file cut short (a copy interrupted, a disk that filled) beside its scene
    description does not read whole: --skip-existing renders that frame again, and says so."""
    assert _render(blend, tmp_path, "--frames", "1") == 0
    exr = tmp_path / "passes_0001.exr"
    data = exr.read_bytes()
    exr.write_bytes(data[: len(data) // 2])
    capsys.readouterr()
    assert _render(blend, tmp_path, "--frames", "1", "--skip-existing") == 0
    out = capsys.readouterr().out
    assert "does not read whole" in out and f"Saved: '{exr}'" in out
    assert exr.read_bytes() != data[: len(data) // 2]


def test_threads_and_device_apply_while_rendering_and_are_put_back(blend, tmp_path, monkeypatch, capsys):
    import bpy

    from sss_lab.blender import render_passes as rp

    seen = []
    real = rp._render

    def spy(scene):
        seen.append((scene.render.threads_mode, scene.render.threads, scene.cycles.device))
        real(scene)

    monkeypatch.setattr(rp, "_render", spy)
    assert _render(blend, tmp_path, "--frames", "1", "--threads", "1", "--device", "cpu") == 0
    assert seen == [("FIXED", 1, "CPU")]
    assert "render: 1 render thread(s), Cycles device CPU" in capsys.readouterr().out
    assert bpy.context.scene.render.threads_mode == "AUTO"  # the file's own setting again


def test_a_device_this_machine_lacks_is_a_clear_error(blend, tmp_path, capsys):
    import bpy

    prefs = bpy.context.preferences.addons["cycles"].preferences
    prefs.refresh_devices()
    if any(d.type == "CUDA" for d in prefs.devices):
        pytest.skip("this machine has a CUDA device")
    assert _render(blend, tmp_path, "--frames", "1", "--device", "CUDA") == 2
    err = capsys.readouterr().err
    assert "no CUDA device on this machine" in err and "--device CPU" in err
    assert not any(tmp_path.iterdir())  # nothing rendered


def test_cli_and_service_list_the_same_devices():
    from sss_lab.addon.cli_options import DEVICES
    from sss_lab.blender.device import DEVICES as SERVICE_DEVICES

    assert DEVICES == SERVICE_DEVICES
