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
