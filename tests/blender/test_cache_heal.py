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
