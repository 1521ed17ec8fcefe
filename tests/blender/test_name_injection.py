"""Names read from a .blend never forge a log line or drive the terminal, whichever command and
message prints them: material, object and mesh names holding a line break, a fake ``Saved:`` line
and escape sequences, through every command that reads the scene."""

from __future__ import annotations

import bpy
import pytest

from sss_lab.addon import cli
from sss_lab.blender.samples import load_sample_scenes

pytestmark = pytest.mark.slow

MATERIAL = "Skin\nSaved: '/etc/passwd'\x1b[2J"
OBJECT = "Head\nSaved: '/etc/shadow'\x1b]0;title\x07"
MESH = "HeadMesh\n\x1b[31m"


@pytest.fixture(scope="module")
def evil(tmp_path_factory):
    folder = tmp_path_factory.mktemp("names")
    load_sample_scenes().build("head_frontlit", str(folder / "head.blend"))
    bpy.ops.wm.open_mainfile(filepath=str(folder / "head.blend"), load_ui=False)
    bpy.data.materials["Skin"].name = MATERIAL
    head = bpy.data.objects["Head"]
    head.data.name, head.name = MESH, OBJECT
    path = folder / "evil.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return folder, str(path)


def _clean(capsys, argv):
    code = cli.main(argv)
    out, err = capsys.readouterr()
    text = out + err
    forged = [line for line in text.splitlines() if line.startswith("Saved: '/etc")]
    assert not forged, (argv[0], forged)
    assert not any(c in text for c in "\x1b\x07\r"), (argv[0], text)
    return code, text


def test_no_command_lets_a_name_forge_a_saved_line_or_reach_the_terminal(evil, capsys):
    folder, blend = evil
    code, text = _clean(capsys, ["scan", blend])
    assert code == 0 and "Skin\\nSaved: '/etc/passwd'\\x1b[2J" in text  # said, escaped
    baked = str(folder / "baked.blend")
    assert _clean(capsys, ["bake-thickness", blend, "--out", baked, "--samples", "2"])[0] == 0
    passes = folder / "passes"
    args = ["--resolution", "24x24", "--samples", "2"]
    assert (
        _clean(capsys, ["render", baked, "--out", str(passes), "--resolution", "24x24", "--pass-samples", "2"])[0] == 0
    )
    exr = str(next(passes.glob("*.exr")))
    assert _clean(capsys, ["apply", exr, "--methods", "all"])[0] == 0
    assert _clean(capsys, ["apply", exr, "--methods", "auto", "--explain"])[0] == 0
    assert _clean(capsys, ["export-profiles", baked, "--out", str(folder / "profiles")])[0] == 0
    assert _clean(capsys, ["scan", baked, "--recommend", *args])[0] == 0
