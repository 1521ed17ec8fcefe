"""The command line's shared options (``addon/cli_options.py``): one meaning, one help and one
parser per option in every command that takes it (no bpy needed to build the parser)."""

import argparse
import os

import pytest

from sss_lab.addon import cli, cli_options


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _option(p: argparse.ArgumentParser, flag: str):
    return next((a for a in p._actions if flag in a.option_strings), None)


def test_scene_means_a_scene_of_the_blend_file_everywhere():
    commands = _commands()
    takers = {name: _option(p, "--scene") for name, p in commands.items() if _option(p, "--scene")}
    assert {"scan", "render", "compare", "bake-thickness", "calibrate", "reference"} <= set(takers)
    assert len({a.help for a in takers.values()}) == 1
    for name, p in commands.items():
        if name not in takers:  # the commands without a .blend file
            assert not any(a.dest == "blend" for a in p._actions), name
    assert _option(commands["apply"], "--description") is not None
    assert _option(commands["demo"], "--sample") is not None


def test_resolution_is_a_render_size_and_methods_are_techniques_everywhere():
    commands = _commands()
    resolution = {name: _option(p, "--resolution") for name, p in commands.items() if _option(p, "--resolution")}
    assert {"render", "compare", "calibrate", "reference", "scan"} <= set(resolution)
    assert all(a.metavar == "WxH" and a.type is None for a in resolution.values())  # read by read_resolution
    assert _option(commands["bake-thickness"], "--image-size") is not None  # an image size is not a --resolution
    methods = [_option(p, "--methods") for name, p in commands.items() if name in ("render", "compare")]
    assert all("sta, ssss, burley, combined" in a.help for a in methods)


def test_resolution_is_read_by_one_parser_with_the_flag_in_the_error():
    args = argparse.Namespace(resolution="640x480")
    assert cli_options.read_resolution(args) == (640, 480)
    assert cli_options.read_resolution(argparse.Namespace(resolution=None)) is None
    with pytest.raises(cli.CommandError, match=r"^--resolution: resolution: expected WIDTHxHEIGHT like 640x480"):
        cli_options.read_resolution(argparse.Namespace(resolution="64"))


def test_integer_options_are_checked_with_their_flag():
    cli_options.check_at_least(argparse.Namespace(samples=1, pass_samples=None), 1, "samples", "pass_samples")
    with pytest.raises(cli.CommandError, match=r"^--pass-samples: expected an integer >= 1, got 0$"):
        cli_options.check_at_least(argparse.Namespace(pass_samples=0), 1, "pass_samples")


def test_apply_help_shows_param(capsys):
    with pytest.raises(SystemExit):
        cli.main(["apply", "--help"])
    out = capsys.readouterr().out
    assert "--param KEY=VALUE" in out and "TECHNIQUE.KEY=VALUE" in out


def test_every_command_takes_the_shared_options_with_one_help(capsys):
    """--debug, --quiet and --log-level in every subcommand's help, worded once; --version."""
    commands = _commands()
    for flag in ("--debug", "--quiet", "--log-level"):
        helps = {name: _option(p, flag).help for name, p in commands.items()}
        assert len(set(helps.values())) == 1, (flag, helps)
        for name, p in commands.items():
            assert flag in p.format_help(), (name, flag)
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith("SSS Lab ")


@pytest.mark.parametrize("flags", [["--quiet"], ["--log-level", "error"], ["--log-level", "warning"]])
def test_quiet_keeps_the_saved_lines_and_the_errors(tmp_path, capsys, flags):
    import json

    import numpy as np

    from sss_lab.core.scene import exr

    parts = tmp_path / "parts"
    parts.mkdir()
    for seed in (1, 2):
        exr.write_layers(
            str(parts / f"reference_seed_{seed:05d}.exr"), {"ViewLayer.Combined": np.full((4, 4, 4), 0.5, np.float32)}
        )
        meta = {"samples": 4, "seed": seed, "fingerprint": "f"}
        (parts / f"reference_seed_{seed:05d}.json").write_text(json.dumps(meta))
    out = tmp_path / "m.exr"
    assert cli.main(["merge-reference", str(parts), "--out", str(out), *flags]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed == [f"Saved: '{out}'", f"Saved: '{tmp_path / 'm.json'}'"]
    assert cli.main(["merge-reference", str(parts), "--out", str(out), *flags]) == 2  # exists: said on stderr
    assert "refusing to overwrite" in capsys.readouterr().err


def test_every_command_states_its_exit_status():
    for name, p in _commands().items():
        text = " ".join(p.format_help().split())
        assert "Exit status: 0 " in text, name
        assert "130 when interrupted" in text and "without --overwrite are bad input, 2" in text, name


def test_the_console_script_names_itself_in_its_usage(capsys, monkeypatch):
    monkeypatch.setattr("sys.argv", ["sss-lab", "--help"])
    with pytest.raises(SystemExit):
        cli.main(prog="sss-lab")
    assert capsys.readouterr().out.startswith("usage: sss-lab ")
    import tomllib

    with open(os.path.join(os.path.dirname(cli.__file__), "..", "pyproject.toml"), "rb") as fh:
        scripts = tomllib.load(fh)["project"]["scripts"]
    assert scripts["sss-lab"] == "sss_lab.addon.cli:script"


def test_every_command_takes_json_and_a_summary_says_what_the_run_did(tmp_path, capsys):
    import json

    import numpy as np

    from sss_lab.core.scene import exr

    for name, p in _commands().items():
        assert _option(p, "--json") is not None, name
    parts = tmp_path / "parts"
    parts.mkdir()
    for seed in (1, 2):
        exr.write_layers(
            str(parts / f"reference_seed_{seed:05d}.exr"), {"ViewLayer.Combined": np.full((4, 4, 4), 0.5, np.float32)}
        )
        (parts / f"reference_seed_{seed:05d}.json").write_text(
            json.dumps({"samples": 4, "seed": seed, "fingerprint": "f"})
        )
    summary = tmp_path / "run.json"
    out = tmp_path / "m.exr"
    assert cli.main(["merge-reference", str(parts), "--out", str(out), "--json", str(summary)]) == 0
    assert f"Saved: '{summary}'" in capsys.readouterr().out
    data = json.loads(summary.read_text())
    assert data["exit_status"] == 0 and data["error"] is None
    assert data["saved"] == [str(out), str(tmp_path / "m.json")]
    assert any("noise floor" in line for line in data["printed"])
    # A failed run says why; an existing summary is not replaced without --overwrite.
    assert cli.main(["merge-reference", str(parts), "--out", str(out), "--json", str(tmp_path / "two.json")]) == 2
    failed = json.loads((tmp_path / "two.json").read_text())
    assert failed["exit_status"] == 2 and "refusing to overwrite" in failed["error"] and failed["saved"] == []
    assert cli.main(["merge-reference", str(parts), "--out", str(tmp_path / "n.exr"), "--json", str(summary)]) == 2
    assert "exists; refusing to overwrite it" in capsys.readouterr().err


def test_one_name_per_concept_with_the_old_spelling_kept_and_said(capsys):
    """--methods names techniques in every command; apply and prepare still take --method and say
    which to use."""
    commands = _commands()
    for name in ("apply", "prepare", "render", "compare", "calibrate"):
        assert _option(commands[name], "--methods") is not None, name
    args = cli.build_parser().parse_args(["prepare", "--method", "sta"])
    assert args.method == "sta"
    assert "--method is deprecated; use --methods" in capsys.readouterr().err
    args = cli.build_parser().parse_args(["prepare", "--methods", "sta"])
    assert args.method == "sta" and capsys.readouterr().err == ""


def test_a_message_naming_a_settings_field_names_the_flag_typed():
    assert cli._with_flag("max_error: expected a number >= 0, got -1.0", ["scan", "x", "--max-error", "-1"]) == (
        "--max-error: expected a number >= 0, got -1.0"
    )
    assert cli._with_flag("techniques: expected at least one", ["calibrate", "--methods", ""]).startswith("--methods:")
    assert cli._with_flag("resolution_px: expected 1..16384", ["bake-thickness", "--image-size=99999"]).startswith(
        "--image-size:"
    )
    # Left as it is when the flag was not typed (the value came from elsewhere) or it is no field.
    assert cli._with_flag("max_error: bad", ["scan"]) == "max_error: bad"
    assert cli._with_flag("/tmp/a b.exr: no such file", ["apply"]) == "/tmp/a b.exr: no such file"


def test_pass_samples_is_one_name_for_the_passes_samples(capsys):
    """--samples meant the passes' samples in render and demo, random-walk samples in calibrate:
    render and demo now say --pass-samples, as compare does, and still take --samples with a note."""
    commands = _commands()
    for name in ("render", "demo", "compare"):
        assert _option(commands[name], "--pass-samples") is not None, name
    for name in ("render", "demo"):
        extra = ["x.blend", "--out", "o"] if name == "render" else ["--out", "o"]
        args = cli.build_parser().parse_args([name, *extra, "--samples", "4"])
        assert args.pass_samples == 4
        assert "--samples is deprecated; use --pass-samples" in capsys.readouterr().err


def test_frames_is_the_one_name_for_frames_and_one_frame_commands_take_one(capsys):
    commands = _commands()
    for name in ("render", "apply", "compare", "reference"):
        assert _option(commands[name], "--frames") is not None, name
    args = cli.build_parser().parse_args(["compare", "x.blend", "--out", "o", "--frames", "3"])
    assert args.frame == 3 and capsys.readouterr().err == ""
    args = cli.build_parser().parse_args(
        ["reference", "x.blend", "--out", "o", "--seeds", "1", "--samples", "4", "--frame", "2"]
    )
    assert args.frame == 2 and "--frame is deprecated; use --frames" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.build_parser().parse_args(["compare", "x.blend", "--out", "o", "--frames", "1-3"])
    assert "compare one frame; give one, e.g. --frames 3" in capsys.readouterr().err


def test_all_and_auto_stand_alone_in_every_methods_list(tmp_path, capsys):
    """``all`` (and in apply ``auto``) listed with another method, in any order: one line saying
    it stands alone, never "unknown method 'all'" beside a list that holds all. Every command
    whose --methods reads technique names reads them with ``cli.parse_methods``."""
    from sss_lab.core.techniques.registry import TECHNIQUES

    readers = {name for name, p in _commands().items() if _option(p, "--methods") is not None}
    assert readers == {"apply", "render", "compare", "prepare", "calibrate"}  # calibrate: fits, not "all"
    for allow_auto in (False, True):
        alone = ("all", "auto") if allow_auto else ("all",)
        for word in alone:
            for text in [f"{word},{t}" for t in TECHNIQUES] + [f"{t},{word}" for t in TECHNIQUES] + ["all,auto"]:
                if not allow_auto and "auto" in text:
                    continue
                with pytest.raises(ValueError) as err:
                    cli.parse_methods(text, allow_auto=allow_auto)
                message = str(err.value)
                first = "all" if text == "all,auto" else word
                assert message.startswith(f"--methods: {first!r} "), message
                assert "stands alone: it cannot be combined with other methods" in message
                assert "unknown" not in message, message
        assert cli.parse_methods("all,all", allow_auto=allow_auto) == list(TECHNIQUES)
        with pytest.raises(ValueError) as err:
            cli.parse_methods("gaussian", allow_auto=allow_auto)
        assert str(err.value).endswith(f"or {' or '.join(alone)} alone"), str(err.value)
    with pytest.raises(ValueError, match="unknown method 'auto'"):  # render, compare, prepare take no auto
        cli.parse_methods("auto")
    # The commands: exit 2 (bad input), one line on stderr, nothing written.
    for argv in (
        ["apply", tmp_path / "p.exr", "--methods", "all,sta"],
        ["apply", tmp_path / "p.exr", "--methods", "burley,auto"],
        ["prepare", "--methods", "sta,all"],
    ):
        code = cli.main(list(map(str, argv)))
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "cannot be combined with other methods" in err, err
    assert os.listdir(tmp_path) == []
