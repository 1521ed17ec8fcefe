"""core/scene/exr.py: Blender 5.2 and 4.5 multilayer layouts, float32 everywhere, safe writing.

The synthetic files are written with the raw OpenEXR API (not with ``write_layers``), using the
part and channel names a bpy 5.2.3 render wrote (tests/blender/test_exr_render.py reads a
real one) and the single-part, short-name layout docs/references.md §7 describes for 4.5.
"""

import os

import numpy as np
import OpenEXR
import pytest

from sss_lab.core.base.errors import OutputError
from sss_lab.core.scene import exr
from sss_lab.core.scene.exr import MissingPassError, Passes, read_layers, read_passes, write_layers

H, W = 5, 7


def plane(value, dtype=np.float32):
    """(H, W) array whose pixel (y, x) is value + y * 10 + x / 10: rows and columns tell apart."""
    y, x = np.mgrid[0:H, 0:W]
    return (value + y * 10.0 + x / 10.0).astype(dtype)


def part(name, channels, **header):
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **header}
    return OpenEXR.Part(hdr, channels, name)


def write_blender52(path, colour_dtype=np.float32):
    """One part per pass, named exactly as bpy 5.2.3 names them (probe render, 64x48)."""
    vl = "ViewLayer"

    def rgb(pass_name, base, letters="RGB"):
        return part(
            f"{vl}.{pass_name}",
            {f"{vl}.{pass_name}.{c}": plane(base + i, colour_dtype) for i, c in enumerate(letters)},
        )

    def data(pass_name, letters, base):
        return part(
            f"{vl}.{pass_name}", {f"{vl}.{pass_name}.{c}": plane(base + i, np.float32) for i, c in enumerate(letters)}
        )

    parts = [
        rgb("Combined", 100, "RGBA"),
        data("Depth", "Z", 200),
        data("Position", "XYZ", 300),
        data("Normal", "XYZ", 400),
        data("Vector", "XYZW", 500),
        data("UV", "UVA", 600),
        data("Object Index", "X", 700),
        data("Material Index", "X", 800),
        rgb("Diffuse Direct", 900),
        rgb("Diffuse Indirect", 1000),
        rgb("Diffuse Color", 1100),
        rgb("Ambient Occlusion", 1200),
        data("Thickness", "X", 1300),
        rgb("Tint", 1400, "RGBA"),
    ]
    # Blender puts its metadata in the first part only.
    parts[0] = part(
        "ViewLayer.Combined",
        {f"{vl}.Combined.{c}": plane(100 + i, colour_dtype) for i, c in enumerate("RGBA")},
        Software="Blender 5.2.3 LTS",
        Frame="001",
        BlenderMultiChannel="Blender V2.55.1 and newer",
    )
    OpenEXR.File(parts).write(str(path))


def write_blender45(path):
    """A single part with Blender 4.x short pass names; colour channels in half, data in float."""
    vl = "ViewLayer"
    channels = {}
    for short, letters, base, dtype in (
        ("Combined", "RGBA", 100, np.float16),
        ("Depth", "Z", 200, np.float32),
        ("Normal", "XYZ", 400, np.float32),
        ("Position", "XYZ", 300, np.float32),
        ("IndexOB", "X", 700, np.float32),
        ("IndexMA", "X", 800, np.float32),
        ("DiffDir", "RGB", 900, np.float16),
        ("DiffInd", "RGB", 1000, np.float16),
        ("DiffCol", "RGB", 1100, np.float16),
        ("GlossDir", "RGB", 1200, np.float16),
        ("TransCol", "RGB", 1250, np.float16),
        ("VolumeDir", "RGB", 1270, np.float16),
        ("Emit", "RGB", 1280, np.float16),
        ("Env", "RGB", 1290, np.float16),
        ("AO", "RGB", 1295, np.float16),
        ("Thickness", "X", 1300, np.float32),
    ):
        for i, c in enumerate(letters):
            channels[f"{vl}.{short}.{c}"] = plane(base + i, dtype)
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(str(path))


def expected(base, n, dtype=np.float32):
    """What a pass built by ``plane(base + i)`` for channel i must read back as (float32)."""
    arrays = [plane(base + i, dtype).astype(np.float32) for i in range(n)]
    return arrays[0] if n == 1 else np.stack(arrays, axis=-1)


def test_blender52_layout_names_shapes_and_channel_order(tmp_path):
    path = tmp_path / "passes.exr"
    write_blender52(path)
    p = read_passes(path)
    assert p.view_layer == "ViewLayer"
    assert p.shape == (H, W)
    assert set(p.names) == {
        "Combined",
        "Depth",
        "Position",
        "Normal",
        "Vector",
        "UV",
        "Object Index",
        "Material Index",
        "Diffuse Direct",
        "Diffuse Indirect",
        "Diffuse Color",
        "Ambient Occlusion",
        "Thickness",
        "Tint",
    }
    # Channels come back in Blender's order (R G B A, X Y Z W, U V A), whatever order the file
    # stores them in (OpenEXR sorts channel names alphabetically: A B G R).
    for name, base, n in (
        ("Combined", 100, 4),
        ("Depth", 200, 1),
        ("Position", 300, 3),
        ("Normal", 400, 3),
        ("Vector", 500, 4),
        ("UV", 600, 3),
        ("Object Index", 700, 1),
        ("Material Index", 800, 1),
        ("Diffuse Direct", 900, 3),
        ("Thickness", 1300, 1),
        ("Tint", 1400, 4),
    ):
        assert p[name].dtype == np.float32, name
        np.testing.assert_array_equal(p[name], expected(base, n), err_msg=name)
    assert p.header["Software"] == "Blender 5.2.3 LTS"
    assert "channels" not in p.header and "dataWindow" not in p.header
    assert "Blender 5" in p.layout


def test_rows_run_top_to_bottom(tmp_path):
    # Row 0 of the array is the first scanline of the file (top of the image, increasing y).
    path = tmp_path / "rows.exr"
    write_blender52(path)
    depth = read_passes(path)["Depth"]
    np.testing.assert_array_equal(depth[:, 0], 200 + 10.0 * np.arange(H))


def test_blender45_single_part_short_names_map_to_long_names(tmp_path):
    path = tmp_path / "passes45.exr"
    write_blender45(path)
    contents = read_layers(path)
    assert contents.parts == 1
    p = read_passes(path)
    for long_name, base, n, dtype in (
        ("Combined", 100, 4, np.float16),
        ("Depth", 200, 1, np.float32),
        ("Normal", 400, 3, np.float32),
        ("Position", 300, 3, np.float32),
        ("Object Index", 700, 1, np.float32),
        ("Material Index", 800, 1, np.float32),
        ("Diffuse Direct", 900, 3, np.float16),
        ("Diffuse Indirect", 1000, 3, np.float16),
        ("Diffuse Color", 1100, 3, np.float16),
        ("Glossy Direct", 1200, 3, np.float16),
        ("Transmission Color", 1250, 3, np.float16),
        ("Volume Direct", 1270, 3, np.float16),
        ("Emission", 1280, 3, np.float16),
        ("Environment", 1290, 3, np.float16),
        ("Ambient Occlusion", 1295, 3, np.float16),
        ("Thickness", 1300, 1, np.float32),
    ):
        assert p[long_name].dtype == np.float32, long_name
        np.testing.assert_array_equal(p[long_name], expected(base, n, dtype), err_msg=long_name)
    assert not ({"DiffDir", "IndexMA", "IndexOB", "Emit", "Env", "AO"} & set(p.names))
    assert "Blender 4" in p.layout


def test_half_channels_become_float32_exactly(tmp_path):
    path = tmp_path / "half.exr"
    write_blender52(path, colour_dtype=np.float16)
    p = read_passes(path)
    stored = plane(900, np.float16)
    assert p["Diffuse Direct"].dtype == np.float32
    # float16 -> float32 is exact, so the values are the half values themselves.
    np.testing.assert_array_equal(p["Diffuse Direct"][..., 0], stored.astype(np.float32))
    assert "Diffuse Direct" in p.half and "Depth" not in p.half


def test_values_above_half_range_survive_write_and_read(tmp_path):
    path = tmp_path / "big.exr"
    big = np.array([[65504.0, 65520.0, 1e6], [3.0e38, np.inf, -1e9]], dtype=np.float32)
    nan = np.full((2, 3), np.nan, dtype=np.float32)
    write_layers(path, {"ViewLayer.Combined": np.stack([big, big, big, nan], axis=-1), "ViewLayer.Depth": big})
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for i in range(len(f.parts)):
            for name, ch in f.channels(i).items():
                assert ch.type() == OpenEXR.FLOAT, name  # never written as half
    p = read_passes(path)
    np.testing.assert_array_equal(p["Depth"], big)  # 65520 and 1e6 would be inf in half
    np.testing.assert_array_equal(p["Combined"][..., 0], big)
    assert np.isnan(p["Combined"][..., 3]).all()


def test_write_layers_widens_half_input_and_names_channels_like_blender(tmp_path):
    path = tmp_path / "out.exr"
    half = plane(1.5, np.float16)
    write_layers(
        path,
        {
            "ViewLayer.Normal": np.stack([half] * 3, axis=-1),
            "ViewLayer.Depth": half,
            "SSSLab.burley.Image": np.zeros((H, W, 4), np.float32),
            "SSSLab.burley.SSS": np.zeros((H, W, 3), np.float32),
        },
        {"sss_lab.scene": '{"version": 1}', "channels": "ignored structural key"},
    )
    with OpenEXR.File(str(path), separate_channels=True) as f:
        names = {p.name(): sorted(f.channels(i)) for i, p in enumerate(f.parts)}
        assert f.header(0)["sss_lab.scene"] == '{"version": 1}'
    assert names == {
        "ViewLayer.Normal": ["ViewLayer.Normal.X", "ViewLayer.Normal.Y", "ViewLayer.Normal.Z"],
        "ViewLayer.Depth": ["ViewLayer.Depth.Z"],
        "SSSLab.burley.Image": [f"SSSLab.burley.Image.{c}" for c in "ABGR"],
        "SSSLab.burley.SSS": [f"SSSLab.burley.SSS.{c}" for c in "BGR"],
    }
    contents = read_layers(path)
    assert contents.half == set()
    assert contents.view_layers == ["ViewLayer", "SSSLab.burley"]
    # The input view layer is chosen over SSS Lab's own output layers.
    assert read_passes(path).view_layer == "ViewLayer"
    assert set(read_passes(path, "SSSLab.burley").names) == {"Image", "SSS"}


def test_write_refuses_to_overwrite(tmp_path):
    path = tmp_path / "existing.exr"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="refusing to overwrite"):
        write_layers(path, {"ViewLayer.Depth": np.ones((2, 2), np.float32)})
    assert path.read_bytes() == b"precious"
    # overwrite=True replaces an ordinary file but never one of the inputs.
    with pytest.raises(FileExistsError, match="input"):
        write_layers(path, {"ViewLayer.Depth": np.ones((2, 2), np.float32)}, overwrite=True, inputs=[path])
    assert path.read_bytes() == b"precious"
    write_layers(path, {"ViewLayer.Depth": np.ones((2, 2), np.float32)}, overwrite=True)
    np.testing.assert_array_equal(read_passes(path)["Depth"], np.ones((2, 2)))
    assert sorted(os.listdir(tmp_path)) == ["existing.exr"]  # no temporary file left


def test_write_is_atomic_when_writing_fails(tmp_path, monkeypatch):
    path = tmp_path / "new.exr"

    class Exploding:
        def __init__(self, parts):
            pass

        def write(self, filename):
            with open(filename, "wb") as fh:
                fh.write(b"half a file")
            raise RuntimeError("disk full")

    monkeypatch.setattr(OpenEXR, "File", Exploding)
    # The writer's RuntimeError becomes one OutputError (an OSError) naming the file.
    with pytest.raises(OutputError, match=r"new.exr: could not be written \(disk full\)"):
        write_layers(path, {"ViewLayer.Depth": np.ones((2, 2), np.float32)})
    assert os.listdir(tmp_path) == []  # neither the target nor the partial temporary file


def test_written_file_has_ordinary_permissions(tmp_path):
    path = tmp_path / "perm.exr"
    write_layers(path, {"ViewLayer.Depth": np.ones((2, 2), np.float32)})
    umask = os.umask(0)
    os.umask(umask)
    assert os.stat(path).st_mode & 0o777 == 0o666 & ~umask


def test_missing_pass_names_the_pass_the_need_and_how_to_enable_it(tmp_path):
    path = tmp_path / "passes.exr"
    write_blender52(path)
    p = read_passes(path)
    with pytest.raises(MissingPassError) as info:
        p.require("Diffuse Indirect2", "Burley")
    msg = str(info.value)
    assert "'Diffuse Indirect2'" in msg and "Burley" in msg and "Shader AOV" in msg
    p2 = Passes({"Combined": np.zeros((2, 2, 4), np.float32)})
    with pytest.raises(MissingPassError) as info:
        p2.require("Diffuse Direct", "SSSS")
    msg = str(info.value)
    assert "'Diffuse Direct'" in msg and "SSSS" in msg
    assert "View Layer Properties > Passes > Light > Diffuse > Direct" in msg
    with pytest.raises(MissingPassError, match="Material Index.*Pass Index"):
        p2["Material Index"]


def test_short_name_kept_when_long_name_also_present(tmp_path):
    # An AOV that happens to be called like a 4.x pass must not replace the real pass.
    path = tmp_path / "clash.exr"
    write_layers(
        path,
        {"ViewLayer.Diffuse Direct": np.ones((2, 2, 3), np.float32), "ViewLayer.DiffDir": np.zeros((2, 2), np.float32)},
    )
    p = read_passes(path)
    assert p["Diffuse Direct"].shape == (2, 2, 3) and p["DiffDir"].shape == (2, 2)


def test_unknown_view_layer_lists_the_known_ones(tmp_path):
    path = tmp_path / "passes.exr"
    write_blender52(path)
    with pytest.raises(ValueError, match="no view layer 'Other'.*ViewLayer"):
        read_passes(path, "Other")


def test_unreadable_and_missing_files(tmp_path):
    bad = tmp_path / "bad.exr"
    bad.write_bytes(b"not an exr")
    with pytest.raises(ValueError, match="not a readable OpenEXR file"):
        read_passes(bad)
    with pytest.raises(FileNotFoundError):
        read_passes(tmp_path / "missing.exr")


def test_passes_are_read_only_float32_and_validated(tmp_path):
    half = np.ones((3, 4, 3), np.float16)
    p = Passes({"Diffuse Color": half, "Depth": np.ones((3, 4), np.float64)})
    assert p["Diffuse Color"].dtype == np.float32 and p["Depth"].dtype == np.float32
    with pytest.raises(ValueError, match="read-only"):
        p["Depth"][0, 0] = 5
    assert half.flags.writeable  # the caller's array is untouched
    with pytest.raises(ValueError, match="differs"):
        Passes({"A": np.ones((3, 4)), "B": np.ones((4, 4))})
    with pytest.raises(ValueError, match="letters"):
        exr.write_layers(tmp_path / "x.exr", {"L.A": np.ones((2, 2, 3))}, channels={"L.A": "RG"})
    assert os.listdir(tmp_path) == []


def _deep(values):
    """Deep pixels holding one sample each, as OpenEXR's Python API writes them."""
    out = np.empty(values.shape, dtype=object)
    for index in np.ndindex(values.shape):
        out[index] = np.array([values[index]], dtype=values.dtype)
    return out


@pytest.mark.parametrize(
    "layout, where",
    [
        ("deepscanline", "the image is a deep scanline image"),
        ("deeptile", "the image is a deep tiled image"),
        ("one part of several", "part 1 'ViewLayer.Depth' is a deep scanline image"),
        ("every part", r"part 0 'ViewLayer.Combined' is a deep scanline image \(2 of its 2 parts are deep\)"),
    ],
)
def test_deep_images_are_refused_naming_the_file_and_the_part(tmp_path, layout, where):
    """Deep parts (any number of samples per pixel) are not Blender's passes: every kind of deep
    part, alone or among flat ones, is refused before any pixel is read, naming it."""
    path = tmp_path / "passes.exr"
    flat = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    deep = {"compression": OpenEXR.ZIPS_COMPRESSION, "type": OpenEXR.deepscanline}
    combined = {f"ViewLayer.Combined.{c}": plane(i) for i, c in enumerate("RGBA")}
    depth = {"ViewLayer.Depth.Z": plane(200)}
    if layout == "deepscanline":
        parts = [OpenEXR.Part(deep, {k: _deep(v) for k, v in combined.items()}, "ViewLayer.Combined")]
    elif layout == "deeptile":
        tiles = OpenEXR.TileDescription()
        tiles.xSize = tiles.ySize = 4
        tiled = {**deep, "type": OpenEXR.deeptile, "tiles": tiles}
        parts = [OpenEXR.Part(tiled, {k: _deep(v) for k, v in combined.items()}, "ViewLayer.Combined")]
    elif layout == "one part of several":
        parts = [
            OpenEXR.Part(flat, combined, "ViewLayer.Combined"),
            OpenEXR.Part(deep, {k: _deep(v) for k, v in depth.items()}, "ViewLayer.Depth"),
        ]
    else:
        parts = [
            OpenEXR.Part(dict(deep), {k: _deep(v) for k, v in combined.items()}, "ViewLayer.Combined"),
            OpenEXR.Part(dict(deep), {k: _deep(v) for k, v in depth.items()}, "ViewLayer.Depth"),  # a header each
        ]
    OpenEXR.File(parts).write(str(path))
    before = path.read_bytes()
    with pytest.raises(ValueError, match=rf"^{str(path)}: {where}; SSS Lab reads flat \(non-deep\) multilayer EXRs"):
        read_passes(path)
    assert path.read_bytes() == before and os.listdir(tmp_path) == ["passes.exr"]
