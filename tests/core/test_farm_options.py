"""The command line's farm options without Blender: frame ranges as farms write them, and the
shared ``--overwrite``/``--skip-existing``/``--threads``/``--device`` options."""

import pytest

from sss_lab.addon import cli
from sss_lab.core.pipeline.sequence import parse_frames


def test_frames_accept_the_ranges_farm_managers_write():
    assert parse_frames("1-3") == [1, 2, 3]  # Flamenco's frameChunker, Blender
    assert parse_frames("1,2") == [1, 2]  # an OpenJD chunk
    assert parse_frames("1-9:4") == [1, 5, 9]  # an OpenJD range with a step
    assert parse_frames("3, 5-6, 10-14:2") == [3, 5, 6, 10, 12, 14]
    with pytest.raises(ValueError, match="step"):
        parse_frames("1-9:0")
    with pytest.raises(ValueError, match="1-10:2"):
        parse_frames("1-9x2")


@pytest.mark.parametrize("command", ["render", "reference", "compare", "bake-thickness"])
def test_blender_rendering_commands_take_threads_and_device(command):
    parser = cli.build_parser()
    args = parser.parse_args(
        [command, "scene.blend", "--out", "o", "--threads", "4", "--device", "optix"]
        + (["--seeds", "1", "--samples", "2"] if command == "reference" else [])
    )
    assert (args.threads, args.device) == (4, "OPTIX")
    args = parser.parse_args(
        [command, "scene.blend", "--out", "o"] + (["--seeds", "1", "--samples", "2"] if command == "reference" else [])
    )
    assert (args.threads, args.device) == (None, None)  # the scene's own settings


@pytest.mark.parametrize("bad", [["--threads", "-1"], ["--threads", "many"], ["--device", "TPU"]])
def test_bad_farm_options_are_refused_with_the_value_named(bad, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.build_parser().parse_args(["render", "scene.blend", "--out", "o", *bad])
    assert exc.value.code == 2
    assert bad[1] in capsys.readouterr().err


@pytest.mark.parametrize("command", ["render", "apply", "reference"])
def test_overwrite_and_skip_existing_exclude_each_other(command, capsys):
    extra = ["--seeds", "1", "--samples", "2"] if command == "reference" else []
    base = [command, "x.exr" if command == "apply" else "scene.blend", "--out", "o"]
    if command == "apply":
        base += ["--methods", "ssss"]
    assert cli.build_parser().parse_args([*base, *extra, "--skip-existing"]).skip_existing
    with pytest.raises(SystemExit):
        cli.build_parser().parse_args([*base, *extra, "--skip-existing", "--overwrite"])
    assert "not allowed with" in capsys.readouterr().err
