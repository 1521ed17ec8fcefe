"""``export-profiles``: each material's profile for HDRP, Unreal and EEVEE, and the baked thickness
images in the bakers' convention, from a scene as its user has it (a fit stored on a material, a
thickness bake), with the input never written."""

from __future__ import annotations

import hashlib
import json
import struct
import zlib

import bpy
import numpy as np
import pytest

from sss_lab.addon.cli import main
from sss_lab.blender.describe import sss_materials
from sss_lab.blender.samples import load_sample_scenes
from sss_lab.blender.stored import write_fit
from sss_lab.core.pipeline.mapping import burley_d
from sss_lab.core.scene.thickness import bakers_map
from sss_lab.core.study import profile_export as pe

pytestmark = pytest.mark.slow


def _read_png16(path) -> np.ndarray:
    data = open(path, "rb").read()
    w, h, depth, colour = struct.unpack(">IIBB", data[16:26])
    assert (depth, colour) == (16, 0)
    raw, pos = b"", 33
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos : pos + 8])
        if kind == b"IDAT":
            raw += data[pos + 8 : pos + 8 + length]
        pos += 12 + length
    rows = np.frombuffer(zlib.decompress(raw), np.uint8).reshape(h, 1 + 2 * w)
    return rows[:, 1:].copy().view(">u2").astype(np.float64) / 65535


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """The sample head with a thickness image baked, and a Burley fit stored on its material."""
    folder = tmp_path_factory.mktemp("export")
    load_sample_scenes().build("head_frontlit", str(folder / "head.blend"))
    bpy.data.objects["Head"].data.uv_layers.new(name="UVMap")  # the image target bakes over a UV map
    src = str(folder / "head_uv.blend")
    bpy.ops.wm.save_as_mainfile(filepath=src, copy=True)
    out = folder / "baked.blend"
    args = ["bake-thickness", src, "--out", str(out), "--target", "image", "--image-size", "16", "--samples", "4"]
    assert main([*args, "--margin", "2"]) == 0
    bpy.ops.wm.open_mainfile(filepath=str(out), load_ui=False)
    write_fit(bpy.data.materials["Skin"], "burley", {"gain": (1.2, 0.9, 0.8), "d_scale": 1.5})
    fitted = folder / "fitted.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(fitted), copy=True)
    return str(fitted)


def test_the_export_carries_the_fitted_profile_and_the_bakers_map(baked, tmp_path, capsys):
    before = hashlib.sha256(open(baked, "rb").read()).hexdigest()
    out = tmp_path / "engines"
    assert main(["export-profiles", baked, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert hashlib.sha256(open(baked, "rb").read()).hexdigest() == before  # the input is never written
    data = json.loads((out / "profiles.json").read_text())
    assert f"Saved: '{out / 'profiles.json'}'" in printed and f"Saved: '{out / 'profiles.md'}'" in printed

    bpy.ops.wm.open_mainfile(filepath=baked, load_ui=False)
    scene = bpy.context.scene
    (skin,) = [m for m in sss_materials(scene) if m.name == "Skin"]
    d = np.array(burley_d(skin)) * 1.5  # the fit's width
    (m,) = data["materials"]
    np.testing.assert_allclose(m["d_su"], d, rtol=1e-9)
    assert m["base_color_gain"] == pytest.approx([1.2, 0.9, 0.8])
    metres = scene.unit_settings.scale_length
    np.testing.assert_allclose(pe.d_from_hdrp(m["hdrp"], metres_per_unit=metres), d, rtol=1e-9)
    np.testing.assert_allclose(pe.d_from_unreal(m["unreal"], metres_per_unit=metres), d, rtol=1e-9)
    np.testing.assert_allclose(pe.d_from_eevee(m["eevee"], skin.base_color), d, rtol=1e-9)
    # The remap gives back the bake distance of the material's objects, in mm.
    assert skin.thickness_distance > 0
    assert m["hdrp"]["thicknessRemap"] == pytest.approx([0.0, skin.thickness_distance * metres * 1000])

    (item,) = data["thickness_maps"]
    image = bpy.data.images[item["image"]]
    w, h = image.size
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    meta = dict(image["sss_lab_thickness"])
    expected = bakers_map(np.clip(px.reshape(h, w, -1)[::-1, :, 0], 0, 1), meta["convention"])
    np.testing.assert_allclose(_read_png16(out / item["file"]), expected, atol=0.5 / 65535 + 1e-7)
    assert item["distance_su"] == pytest.approx(meta["distance_su"])
    assert 0 < item["distance_relative"] <= 1
    assert f"Saved: '{out / item['file']}'" in printed
    page = (out / "profiles.md").read_text()
    assert "## Skin" in page and "Mean Free Path Distance (cm)" in page

    # Again without --overwrite: refused before anything is written, naming the file.
    stamp = (out / "profiles.json").stat().st_mtime_ns
    assert main(["export-profiles", baked, "--out", str(out)]) == 2
    assert "exists; refusing to overwrite it" in capsys.readouterr().err
    assert (out / "profiles.json").stat().st_mtime_ns == stamp
    assert main(["export-profiles", baked, "--out", str(out), "--overwrite", "--albedo-mode", "pre-post"]) == 0
    again = json.loads((out / "profiles.json").read_text())
    assert again["materials"][0]["hdrp"]["texturingMode"] == "PreAndPostScatter"


def test_bad_options_are_named(baked, tmp_path, capsys):
    assert main(["export-profiles", baked, "--out", str(tmp_path / "x"), "--metres-per-unit", "0"]) == 2
    assert "--metres-per-unit 0.0: expected a number > 0" in capsys.readouterr().err
    assert main(["export-profiles", baked, "--out", str(tmp_path / "x"), "--technique", "nope"]) == 2
    assert "--technique" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_the_panel_exports_into_a_folder_and_refuses_to_overwrite(addon, baked, tmp_path):
    bpy.ops.wm.open_mainfile(filepath=baked, load_ui=False)
    folder = tmp_path / "panel"
    assert bpy.ops.sss_lab.export_profiles(directory=str(folder)) == {"FINISHED"}
    data = json.loads((folder / "profiles.json").read_text())
    assert [m["material"] for m in data["materials"]] == ["Skin"]
    assert (folder / data["thickness_maps"][0]["file"]).is_file()
    stamp = (folder / "profiles.md").stat().st_mtime_ns
    with pytest.raises(RuntimeError, match="exists; refusing to overwrite it"):
        bpy.ops.sss_lab.export_profiles(directory=str(folder))
    assert (folder / "profiles.md").stat().st_mtime_ns == stamp
    assert bpy.ops.sss_lab.export_profiles(directory=str(folder), overwrite=True, albedo_mode="pre-post") == {
        "FINISHED"
    }
    assert json.loads((folder / "profiles.json").read_text())["albedo_mode"] == "pre-post"
