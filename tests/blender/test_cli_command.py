"""``blender --command sss_lab ...``: the extension registers the command line with Blender.

The bpy module has no ``blender`` executable to run ``-c`` with, so the registered callback is
called the way Blender calls it: with the arguments after the command id, expecting an int.
"""

import sss_lab.addon as addon_pkg
from sss_lab.addon import cli


def test_the_command_is_registered_with_the_addon_and_removed_with_it(addon):
    assert addon_pkg._cli_handle is not None
    addon.unregister()
    assert addon_pkg._cli_handle is None
    addon.register()  # the fixture unregisters again
    assert addon_pkg._cli_handle is not None


def test_the_callback_runs_the_commands_and_returns_their_status(capsys, tmp_path):
    assert cli.blender_command(["--help"]) == 0
    out = capsys.readouterr().out
    assert "blender --command sss_lab" in out and "compare" in out
    assert cli.blender_command(["no-such-command"]) == 2  # a usage error, not an exit of Blender
    missing = tmp_path / "passes.exr"
    args = ["apply", str(missing), "--methods", "sta"]
    status = cli.blender_command(args)
    assert status != 0 and str(missing) in capsys.readouterr().err
    assert status == cli.main(args)  # the same status as python -m sss_lab
