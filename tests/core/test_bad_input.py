"""Bad input to the NumPy side: damaged EXRs, scene descriptions that break the schema, outputs
that would replace an input, and frame ranges without end. Each case is one a user met (a
truncated copy, a hand-edited JSON, a units slip); each must give one clear error naming the
file and what to do, and leave every input as it was."""

import dataclasses
import json
import os

import numpy as np
import OpenEXR
import pytest

from sss_lab.core.base.errors import DamagedFileError, InputError, SSSLabError
from sss_lab.core.pipeline import sequence
from sss_lab.core.scene.exr import MissingPassError, read_layers, read_passes, write_layers
from sss_lab.core.scene.scene import SceneDescription
from sss_lab.core.study.synthetic import sphere_scene, write_scene


@pytest.fixture
def scene_files(tmp_path):
    arrays, scene = sphere_scene(width=32, height=24)
    path = str(tmp_path / "passes.exr")
    write_scene(path, arrays, scene)
    return path, arrays, scene


def _bytes(path):
    with open(path, "rb") as fh:
        return fh.read()


def _parts(path):
    return [OpenEXR.File(path, header_only=True).header(i)["name"] for i in range(len(OpenEXR.File(path).parts))]


# --- EXR files ---


def test_a_file_missing_its_last_byte_is_an_error_naming_the_part(scene_files, tmp_path):
    path, _, _ = scene_files
    data = _bytes(path)
    cut = tmp_path / "cut.exr"
    cut.write_bytes(data[:-1])
    # What OpenEXR alone does: the last part is silently left out.
    assert len(OpenEXR.File(str(cut), separate_channels=True).parts) == len(_parts(path)) - 1
    with pytest.raises(DamagedFileError) as err:
        read_layers(cut)
    message = str(err.value)
    last = _parts(path)[-1]
    assert str(cut) in message and repr(last) in message and "truncated or damaged" in message
    assert "render the passes again" in message
    assert isinstance(err.value, SSSLabError) and isinstance(err.value, ValueError)


def test_damaged_bytes_inside_a_compressed_part_are_an_error(scene_files, tmp_path):
    path, _, _ = scene_files
    data = bytearray(_bytes(path))
    # Damage the middle third of the file (pixel data of the passes, ZIP-compressed).
    for i in range(len(data) // 3, 2 * len(data) // 3, 7):
        data[i] ^= 0x5A
    bad = tmp_path / "bad.exr"
    bad.write_bytes(bytes(data))
    with pytest.raises(DamagedFileError, match="bad.exr.*(cannot be read|damaged)"):
        read_layers(bad)


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (b"", "it is empty"),
        (b"hello, I am a text file", "does not start with the OpenEXR signature"),
        (b'{"version": 1}', "looks like JSON"),
    ],
)
def test_not_an_exr_at_all(tmp_path, content, expected):
    path = tmp_path / "passes.exr"
    path.write_bytes(content)
    with pytest.raises(DamagedFileError, match=expected):
        read_layers(path)


def test_a_folder_or_a_missing_file(tmp_path):
    with pytest.raises(InputError, match="is a folder"):
        read_layers(tmp_path)
    with pytest.raises(FileNotFoundError, match="no such EXR file"):
        read_layers(tmp_path / "nothing.exr")


def _write_channels(path, channels):
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(str(path))


def _channels(arrays, drop=(), types=None):
    letters = {"Combined": "RGBA", "Depth": "Z", "Normal": "XYZ", "Position": "XYZ"}
    out = {}
    for name, arr in arrays.items():
        for c, letter in enumerate(letters.get(name, "X" if arr.ndim == 2 else "RGB")):
            full = f"ViewLayer.{name}.{letter}"
            if full in drop:
                continue
            plane = arr if arr.ndim == 2 else arr[..., c]
            out[full] = plane.astype((types or {}).get(name, np.float32))
    return out


def test_a_colour_pass_missing_a_channel_is_named(tmp_path):
    arrays, _ = sphere_scene(width=16, height=12)
    path = tmp_path / "p.exr"
    _write_channels(path, _channels(arrays, drop={"ViewLayer.Diffuse Color.B"}))
    with pytest.raises(InputError) as err:
        read_passes(path)
    message = str(err.value)
    assert "'ViewLayer.Diffuse Color'" in message and "missing B" in message and "render the passes again" in message


def test_depth_stored_as_colour_is_named(tmp_path):
    arrays, _ = sphere_scene(width=16, height=12)
    channels = _channels({k: v for k, v in arrays.items() if k != "Depth"})
    for letter in "RGB":
        channels[f"ViewLayer.Depth.{letter}"] = arrays["Depth"]
    path = tmp_path / "p.exr"
    _write_channels(path, channels)
    with pytest.raises(InputError, match=r"'ViewLayer.Depth' has the channels R, G, B; the Depth pass needs Z"):
        read_passes(path)


def test_integer_light_is_refused_but_integer_indices_are_read(tmp_path):
    arrays, _ = sphere_scene(width=16, height=12)
    path = tmp_path / "ok.exr"
    _write_channels(path, _channels(arrays, types={"Material Index": np.uint32, "Object Index": np.uint32}))
    passes = read_passes(path)
    np.testing.assert_array_equal(passes["Material Index"], arrays["Material Index"])
    bad = tmp_path / "bad.exr"
    _write_channels(bad, _channels(arrays, types={"Diffuse Direct": np.uint32}))
    with pytest.raises(InputError, match=r"'ViewLayer.Diffuse Direct' is stored as UINT .* needs HALF or FLOAT"):
        read_passes(bad)


def test_a_missing_part_names_the_pass_and_where_to_enable_it(tmp_path):
    arrays, scene = sphere_scene(width=16, height=12)
    del arrays["Diffuse Direct"]
    path = str(tmp_path / "p.exr")
    write_scene(path, arrays, scene)
    with pytest.raises(MissingPassError) as err:
        sequence.apply_file(path, ["burley"])
    assert "'Diffuse Direct' is missing" in str(err.value) and "use_pass_diffuse_direct" in str(err.value)
    assert isinstance(err.value, SSSLabError)


def test_data_and_display_windows_are_kept(tmp_path):
    arrays, scene = sphere_scene(width=32, height=24)
    # A render border: 32 x 24 pixels placed at (100, 40) in a 256 x 128 frame.
    windows = ((100, 40, 131, 63), (0, 0, 255, 127))
    path = str(tmp_path / "border.exr")
    write_layers(path, {f"ViewLayer.{k}": v for k, v in arrays.items()}, windows=windows)
    (tmp_path / "border.json").write_text(scene.to_json())
    contents = read_layers(path)
    assert contents.windows == windows
    result = sequence.apply_file(path, ["burley"])
    out = read_layers(result.out_path)
    assert out.windows == windows
    header = OpenEXR.File(result.out_path, header_only=True).header(0)
    assert tuple(header["dataWindow"][0]) == (100, 40) and tuple(header["displayWindow"][1]) == (255, 127)
    with pytest.raises(ValueError, match="data window"):
        write_layers(str(tmp_path / "x.exr"), {"A.Combined": arrays["Combined"]}, windows=((0, 0, 9, 9), windows[1]))


def test_a_damaged_frame_of_a_sequence_fails_instead_of_skipping_a_technique(tmp_path):
    arrays, scene = sphere_scene(width=24, height=16)
    for frame in (1, 2):
        write_scene(str(tmp_path / f"p_{frame:04d}.exr"), arrays, dataclasses.replace(scene, frame=frame))
    damaged = tmp_path / "p_0002.exr"
    damaged.write_bytes(_bytes(damaged)[:-1])  # the last part (Thickness, which STA reads) is lost
    ok = sequence.apply_file(str(tmp_path / "p_0001.exr"), ["sta", "ssss", "burley"], skip_missing=True)
    assert ok.written and not ok.skipped
    with pytest.raises(DamagedFileError, match="p_0002.exr"):
        sequence.apply_file(str(damaged), ["sta", "ssss", "burley"], skip_missing=True)


# --- scene description JSON ---


def _scene_dict():
    return json.loads(sphere_scene(width=16, height=12)[1].to_json())


def _load(data, tmp_path, name="scene.json"):
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return sequence.read_scene_file(str(path))


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda d: d.update(extra_key=1), r"unknown key\(s\) 'extra_key'"),
        (lambda d: d["camera"].update(focal=50), r"camera: unknown key\(s\) 'focal'"),
        (lambda d: d["materials"][1].update(subsurface_radius="123"), r"subsurface_radius: expected a list of three"),
        (lambda d: d["materials"][1].update(subsurface_radius=[1, 2]), r"materials\[1\].subsurface_radius: expected"),
        (lambda d: d["materials"][1].update(subsurface_scale="0.01"), r"subsurface_scale: expected a finite number"),
        (lambda d: d["materials"][1].update(index=1.0), r"materials\[1\].index: expected an integer"),
        (lambda d: d["materials"][1].update(subsurface_ior=0), "subsurface_ior: expected a finite number > 0"),
        (lambda d: d["materials"][1].update(subsurface_anisotropy=5), "subsurface_anisotropy: expected a number in"),
        (lambda d: d["camera"].update(width_px=16.0), "camera.width_px: expected an integer"),
        (lambda d: d["camera"].update(width_px="16"), r"camera.width_px: expected an integer .*, got a string"),
        (lambda d: d["camera"].update(matrix_world=[0.0] * 16), "camera matrix_world: the matrix is degenerate"),
        (lambda d: d["camera"].update(matrix_world=[1.0] * 15), "camera.matrix_world: expected a list of 16"),
        (lambda d: d["lights"][0].update(matrix_world=[0.0] * 16), "matrix_world: the matrix is degenerate"),
        (lambda d: d["lights"][0].update(energy="3"), r"lights\[0\].energy: expected a finite number"),
        (lambda d: d["lights"][0].update(size=-1.0), "size: expected a finite number >= 0"),
        (lambda d: d.update(materials={"a": 1}), "materials: expected a JSON list"),
        (lambda d: d.update(camera=None), "camera: expected a JSON object, got null"),
        (lambda d: d.pop("camera"), r"missing key\(s\) 'camera'"),
        (lambda d: d["lights"].append(5), r"lights\[2\]: expected a JSON object, got the int 5"),
        (lambda d: d.update(frame="one"), "frame: expected an integer"),
    ],
)
def test_schema_errors_name_the_field(tmp_path, edit, expected):
    data = _scene_dict()
    edit(data)
    with pytest.raises(InputError, match=expected) as err:
        _load(data, tmp_path)
    assert str(tmp_path / "scene.json") in str(err.value)


def test_non_finite_json_numbers_are_refused(tmp_path):
    text = json.dumps(_scene_dict()).replace('"lens_mm": 35.0', '"lens_mm": NaN')
    assert "NaN" in text
    with pytest.raises(InputError, match="NaN is not a number JSON allows"):
        _load(text, tmp_path)


def _nested(depth, inner="1"):
    return "[" * depth + inner + "]" * depth


@pytest.mark.parametrize(
    "text",
    [
        _nested(100000),  # beyond what Python's JSON reader takes: RecursionError
        _nested(9000),  # reads, but repr, asdict and deepcopy would recurse past Python's limit
        '{"a": ' * 9000 + "1" + "}" * 9000,
        json.dumps({**_scene_dict(), "meta": {"note": "X"}}).replace('"X"', _nested(101)),
        json.dumps({**_scene_dict(), "version": "X"}).replace('"X"', _nested(5000)),
    ],
    ids=["100000 arrays", "9000 arrays", "9000 objects", "101 levels in meta", "5000 levels as the version"],
)
def test_json_nested_too_deep_is_not_a_scene_description(tmp_path, text):
    """However deep and wherever the nesting, one InputError naming the file: no RecursionError,
    no line of ten thousand brackets."""
    path = tmp_path / "scene.json"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        sequence.read_scene_file(str(path))
    message = str(err.value)
    assert (
        message
        == f"{path}: scene description: arrays or objects nested more than 100 levels deep; not a scene description"
    )
    assert path.read_text() == text


def test_a_number_of_thousands_of_digits_is_named(tmp_path):
    text = json.dumps(_scene_dict()).replace('"frame": 1', '"frame": ' + "1" * 5000)
    with pytest.raises(
        InputError, match=r"scene.json: scene description: a number of more than 4300 digits; not a scene"
    ):
        _load(text, tmp_path)


def test_every_json_a_user_hands_over_is_read_by_the_one_reader(tmp_path):
    """No module parses JSON itself (core/base/jsonfile.py handles nesting, huge numbers and bad
    text for all), and each reader names its file for JSON nested too deep."""
    import ast
    import pathlib

    import sss_lab
    from sss_lab.core.base import jsonfile
    from sss_lab.core.pipeline.auto import load_model
    from sss_lab.core.study.reference import read_meta
    from sss_lab.core.study.report_schema import Report

    root = pathlib.Path(sss_lab.__file__).parent
    parsing = []
    for source in root.rglob("*.py"):
        rel = source.relative_to(root).as_posix()
        top = rel.split("/")[0]
        # The tests and benchmarks read their own files; hidden folders hold the environments
        # (.venv, .venv-4.5 of the set-up), whose packages are not the project's.
        if top in ("tests", "benchmarks") or top.startswith(".") or rel == "core/base/jsonfile.py":
            continue
        for node in ast.walk(ast.parse(source.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute) and node.attr in ("load", "loads", "JSONDecoder", "raw_decode"):
                if isinstance(node.value, ast.Name) and node.value.id == "json":
                    parsing.append(f"{rel}:{node.lineno}")
    assert parsing == [], "parse JSON with core.base.jsonfile.read_json / parse_json"
    deep = tmp_path / "deep.json"
    deep.write_text(_nested(100000))
    for read in (sequence.read_scene_file, read_meta, Report.read, load_model, lambda p: jsonfile.read_json(p, "x")):
        with pytest.raises(InputError, match=f"^{deep}: .*nested more than 100 levels deep"):
            read(str(deep))


def test_a_valid_description_still_round_trips(tmp_path):
    data = _scene_dict()
    assert _load(data, tmp_path).to_dict() == SceneDescription.from_dict(data).to_dict()


def test_an_exr_or_binary_file_given_as_the_scene(scene_files, tmp_path):
    path, _, _ = scene_files
    with pytest.raises(InputError, match="is an OpenEXR file, not a scene description"):
        sequence.read_scene_file(path)
    blob = tmp_path / "blob.json"
    blob.write_bytes(bytes([0xFF, 0xFE, 0x00, 0x95]))
    with pytest.raises(InputError, match="not UTF-8 text"):
        sequence.read_scene_file(str(blob))


# --- outputs ---


def test_the_scene_description_is_never_replaced(scene_files, tmp_path):
    path, _, scene = scene_files
    sidecar = sequence.sidecar_path(path)
    before = _bytes(sidecar)
    roundabout = os.path.join(str(tmp_path), ".", "..", tmp_path.name, "passes.json")
    for spelling in (sidecar, roundabout):
        with pytest.raises(FileExistsError, match="is an input"):
            sequence.apply_file(path, ["burley"], out_path=spelling, overwrite=True)
    other = tmp_path / "other.json"
    other.write_text(scene.to_json())
    link = tmp_path / "link.exr"
    os.symlink(other, link)
    with pytest.raises(FileExistsError, match="is an input"):
        sequence.apply_file(path, ["burley"], out_path=str(link), scene_path=str(other), overwrite=True)
    assert _bytes(sidecar) == before and other.read_text() == scene.to_json()


def test_outputs_that_are_not_files(scene_files, tmp_path):
    path, _, _ = scene_files
    with pytest.raises(ValueError, match="give it the .exr suffix"):
        sequence.apply_file(path, ["burley"], out_path=str(tmp_path / "o.png"))
    folder = tmp_path / "folder.exr"
    folder.mkdir()
    with pytest.raises(FileExistsError, match="is a folder"):
        sequence.apply_file(path, ["burley"], out_path=str(folder), overwrite=True)
    fifo = tmp_path / "fifo.exr"
    os.mkfifo(fifo)
    with pytest.raises(FileExistsError, match="not a regular file"):
        sequence.apply_file(path, ["burley"], out_path=str(fifo), overwrite=True)
    assert os.path.exists(fifo) and not os.path.isfile(fifo)
    assert not [n for n in os.listdir(tmp_path) if n.endswith(".tmp")]


# --- frame ranges ---


def test_a_huge_frame_range_is_refused_at_once():
    with pytest.raises(ValueError, match="more than 100000 frames"):
        sequence.parse_frames("1-100000000")
    with pytest.raises(ValueError, match="more than 100000 frames"):
        sequence.parse_frames("1-60000,100001-160000")
    assert sequence.parse_frames("1-3,7") == [1, 2, 3, 7]
    assert len(sequence.parse_frames(f"1-{sequence.MAX_FRAMES}")) == sequence.MAX_FRAMES


@pytest.mark.parametrize("depth", [0.0, -1.0, np.nan])
def test_a_material_without_a_valid_depth_is_not_reported_computed(depth):
    from sss_lab.core.pipeline.plan import plan
    from sss_lab.core.scene.exr import Passes

    arrays, scene = sphere_scene(width=16, height=12)
    arrays["Depth"] = np.full_like(arrays["Depth"], depth)
    p = plan(Passes(arrays), scene, "burley")
    assert not p.applied
    assert all("valid depth" in m.skip for m in p.scattering if m.pixels)
    assert "render the Depth pass again" in p.explain()
