"""Damaged .blend files given to every command that opens one: one line naming the file and what
to do, exit status 2, the file untouched; never Blender's RuntimeError traceback."""

import hashlib

import bpy
import pytest

from sss_lab.addon import cli


@pytest.fixture(scope="module")
def good_blend(tmp_path_factory):
    path = tmp_path_factory.mktemp("blend") / "good.blend"
    bpy.ops.wm.read_factory_settings(use_empty=False)
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


def _damaged(good: bytes) -> dict[str, bytes]:
    flipped = bytearray(good)
    for i in range(len(good) // 4, len(good), 997):
        flipped[i] ^= 0xFF
    return {
        "text": b"this is not a blend file\n",
        "empty": b"",
        "header only": good[:12],
        "truncated": good[: len(good) // 2],
        "flipped": bytes(flipped),
    }


@pytest.mark.parametrize("command", ["scan", "render", "compare", "bake-thickness", "calibrate"])
def test_a_damaged_blend_is_one_line(good_blend, tmp_path, capsys, command):
    good = good_blend.read_bytes()
    for kind, data in _damaged(good).items():
        path = tmp_path / f"{kind.replace(' ', '_')}.blend"
        path.write_bytes(data)
        argv = [command, str(path)]
        if command != "scan":
            blend_out = command in ("bake-thickness", "calibrate")
            argv += ["--out", str(tmp_path / ("out.blend" if blend_out else f"out_{kind.replace(' ', '_')}"))]
        code = cli.main(argv)
        err = capsys.readouterr().err
        assert code == 2, (kind, err)
        assert err.count("\n") == 1 and "Traceback" not in err, (kind, err)
        assert f"'{path}' cannot be opened as a .blend file" in err and "backup (.blend1)" in err, (kind, err)
        assert hashlib.sha256(path.read_bytes()).digest() == hashlib.sha256(data).digest()


def test_scripts_in_a_blend_never_run_even_when_the_preferences_allow_it(tmp_path, capsys):
    """A .blend holding a text block registered to run on load (and a driver expression): the
    commands open user files with scripts off whatever Blender's preferences say, so the script
    leaves no trace (it would write a file)."""
    from sss_lab.addon.cli_scan import open_blend

    marker = tmp_path / "ran.txt"
    bpy.ops.wm.read_factory_settings(use_empty=True)
    text = bpy.data.texts.new("autorun.py")
    text.write(f"open({str(marker)!r}, 'w').write('ran')\n")
    text.use_module = True  # "Register": Blender runs it when the file loads, if scripts may run
    cube = bpy.data.objects.new("Cube", bpy.data.meshes.new("Cube"))
    bpy.context.scene.collection.objects.link(cube)
    driver = cube.driver_add("location", 0).driver
    driver.type, driver.expression = "SCRIPTED", f"len(open({str(marker)!r}, 'w').write('ran')) * 0"
    path = tmp_path / "scripted.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    prefs = bpy.context.preferences.filepaths
    before = prefs.use_scripts_auto_execute
    prefs.use_scripts_auto_execute = True
    try:
        open_blend(str(path))
    finally:
        prefs.use_scripts_auto_execute = before
    assert "autorun.py" in bpy.data.texts  # the file was opened
    bpy.context.view_layer.update()  # drivers evaluate here, if they may
    assert not marker.exists()
    assert "its scripts were not run" in capsys.readouterr().out  # and the command says so


@pytest.mark.parametrize("damage", ["truncated", "empty"])
def test_a_blend_written_damaged_is_an_error_and_leaves_no_file(tmp_path, monkeypatch, damage):
    """On a full disk Blender's saver can leave a short file and report nothing: the written copy
    is read back before it is moved into place, so the command fails with the write named and
    nothing is left under the output's name (nor a temporary beside it)."""
    from sss_lab.addon import cli_options
    from sss_lab.core.base.errors import OutputError

    real = cli_options._save_copy

    def short_write(path):
        real(path)
        data = open(path, "rb").read()
        open(path, "wb").write(data[: len(data) // 2] if damage == "truncated" else b"")

    bpy.ops.wm.read_factory_settings(use_empty=False)
    monkeypatch.setattr(cli_options, "_save_copy", short_write)
    out = tmp_path / "out.blend"
    with pytest.raises(OutputError, match="out.blend: could not be written"):
        cli_options.save_blend(str(out))
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setattr(cli_options, "_save_copy", real)
    cli_options.save_blend(str(out))  # a whole write is read back and kept
    assert [p.name for p in tmp_path.iterdir()] == ["out.blend"]
    assert len(bpy.data.libraries) == 0  # the read-back linked nothing into the open file


@pytest.mark.parametrize("command", ["bake-thickness", "match-eevee --remove"])
def test_a_blend_output_that_appears_meanwhile_is_not_replaced_without_overwrite(
    tmp_path, monkeypatch, capsys, command
):
    """Two runs started together with one --out both pass the check made at the start; the second
    to finish must refuse, not replace the first's file (and print no Saved line for it)."""
    from sss_lab.addon import cli_options
    from sss_lab.blender.samples import load_sample_scenes

    src = load_sample_scenes().build("head_frontlit", str(tmp_path / "in.blend"))
    out = tmp_path / "out.blend"
    real = cli_options._save_copy

    def other_run_finishes_first(path):
        out.write_bytes(b"the other run's file")
        real(path)

    monkeypatch.setattr(cli_options, "_save_copy", other_run_finishes_first)
    argv = [*command.split(), src, "--out", str(out)] + (["--samples", "2"] if command == "bake-thickness" else [])
    assert cli.main([command.split()[0], *argv[1:]]) == 2
    printed = capsys.readouterr()
    assert "already exists; refusing to overwrite it" in printed.err and "Saved:" not in printed.out
    assert out.read_bytes() == b"the other run's file"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.blend", "out.blend"]  # no temporary left
    out.unlink()
    assert cli.main([command.split()[0], *argv[1:], "--overwrite"]) == 0  # said: replaced
    assert out.read_bytes() != b"the other run's file"
