"""The reference cache heals itself: an entry whose metadata or EXR cannot be read (empty or
damaged JSON, a wrong value, a truncated or replaced EXR, as a crash or a full disk leaves
them) is rendered again with a note, and the metadata is written atomically."""

import json
import os

import bpy
import pytest

from sss_lab.blender import compat
from sss_lab.blender.reference_cache import cached_reference


@pytest.fixture
def cube_scene():
    bpy.ops.wm.read_factory_settings(use_empty=False)
    material = bpy.data.materials.new("Skin")
    compat.ensure_node_tree(material)
    material.node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 1.0
    bpy.data.objects["Cube"].data.materials[0] = material  # the faces use slot 0
    return bpy.context.scene


def _reference(scene, cache, notes):
    return cached_reference(scene, str(cache), samples=2, seed=0, resolution=(16, 16), method=None, log=notes.append)


DAMAGE = {
    "empty metadata": lambda exr, meta: open(meta, "w").close(),
    "metadata cut short": lambda exr, meta: open(meta, "w").write('{"seconds": 1.'),
    "seconds not a number": lambda exr, meta: open(meta, "w").write('{"seconds": "fast"}'),
    "EXR one byte short": lambda exr, meta: open(exr, "r+b").truncate(os.path.getsize(exr) - 1),
    "EXR replaced by text": lambda exr, meta: open(exr, "w").write("not an image"),
    "metadata missing": lambda exr, meta: os.remove(meta),
    "seconds negative": lambda exr, meta: _edit(meta, seconds=-5),
    "seconds beyond any render": lambda exr, meta: _edit(meta, seconds=1e308),
    "metadata a list": lambda exr, meta: open(meta, "w").write("[1, 2]"),
    "samples edited": lambda exr, meta: _edit(meta, samples=999),
    "EXR all NaN": lambda exr, meta: _image(exr, float("nan")),
    "EXR all Inf": lambda exr, meta: _image(exr, float("inf")),
    "EXR of another size": lambda exr, meta: _image(exr, 0.5, size=(8, 8)),
}


def _edit(meta, **values):
    data = json.loads(open(meta).read())
    data.update(values)
    open(meta, "w").write(json.dumps(data))


def _image(path, value, size=(16, 16)):
    import numpy as np

    from sss_lab.core.scene import exr

    os.remove(path)
    exr.write_layers(str(path), {"ViewLayer.Combined": np.full((*size, 4), value, np.float32)})


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_a_damaged_entry_is_rendered_again_with_a_note(cube_scene, tmp_path, damage):
    cache = tmp_path / "cache"
    notes = []
    image, seconds, from_cache = _reference(cube_scene, cache, notes)
    assert not from_cache and image.shape[:2] == (16, 16)
    (exr,) = [cache / n for n in os.listdir(cache) if n.endswith(".exr")]
    meta = exr.with_suffix(".json")
    assert json.loads(meta.read_text())["seconds"] == seconds
    assert _reference(cube_scene, cache, notes)[2]  # an intact entry is reused

    DAMAGE[damage](exr, meta)
    notes.clear()
    again, _, from_cache = _reference(cube_scene, cache, notes)
    assert not from_cache and again.shape == image.shape
    if damage != "metadata missing":  # an entry without metadata is simply not there yet
        assert any(n.startswith(f"note: the cached reference {exr} cannot be used") for n in notes), notes
    assert isinstance(json.loads(meta.read_text())["seconds"], float)  # healed
    assert _reference(cube_scene, cache, notes)[2]  # and reused from then on
    assert sorted(os.listdir(cache)) == sorted([exr.name, meta.name])  # no temporary file


#: Cache folders that cannot be folders: (the --cache given, relative to the case's folder, or
#: None for the default OUT/cache; the file made first).
NOT_FOLDERS = {
    "--cache an existing file": ("afile", "afile"),
    "--cache under a file": ("afile/sub", "afile"),
    "--cache a broken link": ("link", None),
    "OUT/cache a file": (None, "out/cache"),
}


def _blockers(root, cache, made):
    (root / "out").mkdir()
    if made:
        (root / made).write_text("not a folder\n")
    if cache == "link":
        (root / "link").symlink_to(root / "nowhere")
    return None if cache is None else str(root / cache)


@pytest.mark.parametrize("case", sorted(NOT_FOLDERS))
def test_a_cache_that_cannot_be_a_folder_is_refused_before_anything_renders(cube_scene, tmp_path, capsys, case):
    """compare's reference cache where a file (or a broken link) stands: refused at once, naming
    the flag and that it must be a folder, never after the first render found it cannot keep it."""
    from sss_lab.addon.cli import main
    from sss_lab.blender.compare import CompareSettings, compare

    cache, made = NOT_FOLDERS[case]
    cache = _blockers(tmp_path, cache, made)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    blend = tmp_path / "cube.blend"  # never opened: the options are checked first
    args = ["compare", str(blend), "--out", str(tmp_path / "out"), "--no-eevee", "--resolution", "16x16"]
    assert main(args + (["--cache", cache] if cache else [])) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    flag = "--cache" if cache else "--out"
    assert f"sss_lab compare: error: {flag} " in err and "expected a folder for the reference cache" in err, err
    # The same through the Python API (the add-on's operator), before any Cycles render.
    settings = CompareSettings(resolution=(16, 16), reference_samples=2, pass_samples=1, cache_dir=cache, eevee=False)
    lines = []
    with pytest.raises(ValueError, match="is not a folder; expected a folder for the reference cache"):
        compare(cube_scene, str(tmp_path / "out"), settings, log=lines.append)
    assert not any("rendering" in line for line in lines), lines
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # nothing written
