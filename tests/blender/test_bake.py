"""Thickness baking (blender/bake.py, operators/thickness.py) with Cycles on tiny meshes and images.

Expected values come from the closed form of core/scene/thickness.py (derived there from how
Cycles' AO node samples directions: cosine-weighted, returning the unoccluded fraction):
on a face of a slab of thickness t, away from its rim by more than D, inside AO = (t/D)^2
for t < D and 1 beyond, and the translucency convention stores 1 - AO.

Noise bound used throughout: a baked value is the unoccluded fraction of n rays, each
escaping with probability p. For independent rays that is Binomial(n, p) / n with
sigma = sqrt(p (1 - p) / n) (``binomial_sigma``); Cycles' stratified sequence does better,
so tolerances built on it are conservative. Different vertices and texels use different
random seeds, so the mean over k of them has sigma / sqrt(k).
"""

import dataclasses
import json
import math
import os
import struct
import subprocess
import sys
import zlib
from types import SimpleNamespace

import bmesh
import bpy
import numpy as np
import pytest

from sss_lab.blender import bake as bake_mod
from sss_lab.blender import compat
from sss_lab.blender.bake import BakeError, bake_thickness
from sss_lab.blender.bake_nodes import NODE_AOV, NODE_NAME
from sss_lab.blender.stored import META_KEY, thickness_metadata
from sss_lab.core.scene.thickness import BakeSettings, binomial_sigma, slab_unoccluded_fraction
from sss_lab.operators.thickness import SSS_LAB_OT_bake_thickness

D = 0.5  # AO distance of the analytic tests, scene units


# -- scene helpers ---------------------------------------------------------------------------
def _link(name, mesh):
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _box(name, size=(1.0, 1.0, 1.0), location=(0.0, 0.0, 0.0), cuts=0, uv=True):
    """A closed box (flat shaded) centred on ``location``, each edge cut ``cuts`` times."""
    bm = bmesh.new()
    if uv:
        bm.loops.layers.uv.new("UVMap")
    bmesh.ops.create_cube(bm, size=1.0, calc_uvs=uv)
    bmesh.ops.scale(bm, vec=size, verts=bm.verts)
    if cuts:
        bmesh.ops.subdivide_edges(bm, edges=list(bm.edges), cuts=cuts, use_grid_fill=True)
    bmesh.ops.translate(bm, vec=location, verts=bm.verts)
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    return mesh


def _plane(name, width=4.0, segments=16):
    """A flat grid in z = 0, ``width`` wide, UVs spanning 0..1 over it."""
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")
    bmesh.ops.create_grid(bm, x_segments=segments, y_segments=segments, size=1.0, calc_uvs=True)
    xs = [v.co.x for v in bm.verts]
    bmesh.ops.scale(bm, vec=(width / (max(xs) - min(xs)),) * 2 + (1.0,), verts=bm.verts)
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    return mesh


def _coords(mesh):
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def _values(mesh, name):
    attr = mesh.color_attributes[name]
    assert (attr.data_type, attr.domain) == ("FLOAT_COLOR", "POINT")
    rgba = np.empty(len(attr.data) * 4, dtype=np.float32)
    attr.data.foreach_get("color", rgba)
    rgba = rgba.reshape(-1, 4)
    # Grey map: the three channels hold the same value.
    np.testing.assert_array_equal(rgba[:, 0], rgba[:, 1])
    np.testing.assert_array_equal(rgba[:, 0], rgba[:, 2])
    return rgba[:, 0]


def _pixels(image):
    w, h = image.size
    px = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(h, w, 4)  # rows bottom to top, as Blender stores them


def _select(*objects, active=None):
    vl = bpy.context.view_layer
    for o in vl.objects:
        o.select_set(False)
    for o in objects:
        o.select_set(True)
    vl.objects.active = active


def _plain(value):
    if isinstance(value, set):
        return tuple(sorted(value))
    if isinstance(value, bpy.types.ID):
        return value.name
    if hasattr(value, "__len__") and not isinstance(value, str):
        return tuple(value)
    return value


def _snapshot():
    """Everything a bake may touch, besides its results."""
    scene = bpy.context.scene
    vl = bpy.context.view_layer
    bake = scene.render.bake
    skip = {"rna_type", "image_settings"}
    return {
        "engine": scene.render.engine,
        "cycles": {k: getattr(scene.cycles, k) for k in ("samples", "use_adaptive_sampling", "time_limit")}
        | {k: getattr(scene.cycles, k) for k in ("film_exposure", "bake_type", "device")},
        "bake": {
            p.identifier: _plain(getattr(bake, p.identifier))
            for p in bake.bl_rna.properties
            if p.identifier not in skip
        },
        "bake_image": (bake.image_settings.file_format, bake.image_settings.color_depth),
        "selected": sorted(o.name for o in vl.objects if o.select_get()),
        "active": vl.objects.active.name if vl.objects.active else None,
        "hidden": {o.name: (o.hide_get(), o.hide_viewport, o.hide_render, o.hide_select) for o in scene.objects},
        "slots": {o.name: [(s.link, _plain(s.material)) for s in o.material_slots] for o in scene.objects},
        "mesh_materials": {m.name: [_plain(x) for x in m.materials] for m in bpy.data.meshes},
        "colors": {
            m.name: (m.color_attributes.active_color_name, m.color_attributes.default_color_name)
            for m in bpy.data.meshes
        },
        "tmp_attributes": sorted(m.name for m in bpy.data.meshes if "SSSLab_thickness_bake" in m.attributes),
        "materials": sorted(bpy.data.materials.keys()),
        "objects": sorted(bpy.data.objects.keys()),
        "meshes": sorted(bpy.data.meshes.keys()),
    }


def _settings(**kw):
    """Settings of the AO bake (most tests here check Cycles' inside AO: samples, only-local,
    the cosine-weighted slab law) unless a test names its source."""
    kw.setdefault("samples", 16)
    kw.setdefault("source", "ao")
    return BakeSettings(**kw)


def _quiet(_line):
    pass


# -- analytic checks -------------------------------------------------------------------------
def test_slabs_match_the_cosine_weighted_expectation():
    """Slabs 4 wide (rim 1.5 > D away from the checked vertices) of several thicknesses, baked
    in one batch to a colour attribute in the translucency convention."""
    thicknesses = (0.1, 0.2, 0.3, 0.4, 0.6)
    objects = [
        _link(f"Slab {t}", _box(f"Slab {t}", size=(4.0, 4.0, t), location=(0, 5 * i, 0), cuts=8))
        for i, t in enumerate(thicknesses)
    ]
    rays = 256
    progress = []
    results = bake_thickness(
        bpy.context,
        objects,
        _settings(samples=rays, distance_su=D),
        progress=lambda done, total, r: progress.append((done, total, r.object)),
        log=_quiet,
    )
    assert progress == [(i + 1, 5, o.name) for i, o in enumerate(objects)]
    assert [r.status for r in results] == ["baked"] * len(thicknesses)
    assert all(r.distance_su == D and not r.distance_auto and r.samples == rays for r in results)
    for i, (obj, t) in enumerate(zip(objects, thicknesses, strict=True)):
        co = _coords(obj.data)
        top_or_bottom = np.abs(co[:, 2]) > t / 2 - 1e-5
        interior = top_or_bottom & (np.abs(co[:, 0]) < 2.0 - D) & (np.abs(co[:, 1] - 5 * i) < 2.0 - D)
        v = _values(obj.data, "Thickness")[interior]
        assert v.size == 72  # 6 x 6 vertices on the top and on the bottom face
        p = float(slab_unoccluded_fraction(t, D))
        expected = 1.0 - p  # translucency
        if p == 1.0:
            # t > D: no ray can reach the far face; exact, up to float32 rounding of 1 - 1.
            assert np.abs(v).max() <= 1e-6, t
            continue
        sigma = float(binomial_sigma(p, rays))
        # Each vertex within 5 sigma; the mean of the 72 within 5 sigma / sqrt(72).
        assert np.abs(v - expected).max() <= 5 * sigma, (t, v.min(), v.max(), expected)
        tol = 5 * sigma / math.sqrt(v.size)
        assert abs(float(v.mean()) - expected) <= tol, (t, float(v.mean()), expected, tol)
        # The check has the power to reject uniform hemisphere sampling, translucency 1 - t/D.
        assert abs((1.0 - t / D) - expected) > 3 * tol


def test_only_local_decides_whether_other_objects_occlude():
    """A slab thicker than D (nothing of its own within reach of the top face) with a separate
    plate 0.2 under its top face: with Only Local the plate does not count (AO 1); without it
    the top face sees a slab of thickness 0.2 (AO (0.2/D)^2)."""
    slab = _link("Thick", _box("Thick", size=(4.0, 4.0, 1.0), cuts=8))
    plate = _link("Plate", _box("Plate", size=(3.9, 3.9, 0.01), location=(0, 0, 0.3)))
    co = _coords(slab.data)
    top = (co[:, 2] > 0.5 - 1e-5) & (np.abs(co[:, 0]) < 2.0 - D) & (np.abs(co[:, 1]) < 2.0 - D)
    rays = 256
    for only_local, p in ((True, 1.0), (False, float(slab_unoccluded_fraction(0.2, D)))):
        settings = _settings(samples=rays, distance_su=D, only_local=only_local, convention="thickness")
        (result,) = bake_thickness(bpy.context, [slab], settings, log=_quiet)
        assert result.status == "baked"
        v = _values(slab.data, "Thickness")[top]
        sigma = float(binomial_sigma(p, rays))  # see the module docstring
        assert abs(float(v.mean()) - p) <= 5 * sigma / math.sqrt(v.size) + 1e-6, (only_local, float(v.mean()), p)
    assert plate.data.attributes.get("Thickness") is None  # only the named objects are baked


def test_thin_parts_brighter_than_thick_parts_and_the_conventions_are_complements():
    """One mesh with two parts, a thin plate and a thick block, 2 apart; automatic distance."""
    bm = bmesh.new()
    mesh = bpy.data.meshes.new("Parts")
    for size, loc in (((2.0, 2.0, 0.05), (-2.0, 0, 0)), ((2.0, 2.0, 2.0), (2.0, 0, 0))):
        part = _box("part", size=size, location=loc, cuts=2, uv=False)
        bm.from_mesh(part)
        bpy.data.meshes.remove(part)
    bm.to_mesh(mesh)
    bm.free()
    obj = _link("Parts", mesh)
    thin = _coords(mesh)[:, 0] < 0
    for convention, name in (("translucency", "T"), ("thickness", "K")):
        (r,) = bake_thickness(bpy.context, [obj], _settings(convention=convention, attribute_name=name), log=_quiet)
        assert r.status == "baked" and r.distance_auto
    t, k = _values(mesh, "T"), _values(mesh, "K")
    assert t[thin].mean() > t[~thin].mean() + 0.2
    assert k[thin].mean() < k[~thin].mean() - 0.2
    # Same seed, same rays: the two conventions are exact complements (float32 1 - x).
    np.testing.assert_allclose(t + k, 1.0, atol=1e-6)
    # The automatic distance: a quarter of the diagonal of the 6 x 2 x 2 bounding box.
    assert r.distance_su == pytest.approx(0.25 * math.sqrt(36 + 4 + 4), rel=1e-6)  # float32 vertex coords
    meta = thickness_metadata(mesh, "K")
    assert meta["convention"] == "thickness" and meta["meaning"].startswith("1 = thick")
    assert thickness_metadata(mesh, "T")["convention"] == "translucency"


# -- targets, modifiers ----------------------------------------------------------------------
def test_attribute_target_bakes_the_mesh_with_its_modifiers_and_leaves_the_data_alone():
    """A flat plane has nothing to hit inside (translucency 0); with a Solidify modifier it is
    a slab of thickness 0.25, and the original vertices get that slab's value."""
    mesh = _plane("Sheet", segments=8)
    obj = _link("Sheet", mesh)
    mod = obj.modifiers.new("Solidify", "SOLIDIFY")
    mod.thickness = 0.25
    before_co = _coords(mesh).copy()
    before = (len(mesh.vertices), len(mesh.edges), len(mesh.polygons), set(mesh.attributes.keys()))
    rays = 64
    (r,) = bake_thickness(bpy.context, [obj], _settings(samples=rays, distance_su=D), log=_quiet)
    assert r.status == "baked" and r.vertices == 2 * len(mesh.vertices)  # the evaluated shell
    assert (len(mesh.vertices), len(mesh.edges), len(mesh.polygons)) == before[:3]
    np.testing.assert_array_equal(_coords(mesh), before_co)
    assert set(mesh.attributes.keys()) == before[3] | {"Thickness"}
    assert [m.name for m in obj.modifiers] == ["Solidify"]
    co = _coords(mesh)
    interior = (np.abs(co[:, 0]) < 2.0 - D) & (np.abs(co[:, 1]) < 2.0 - D)
    v = _values(mesh, "Thickness")[interior]
    p = float(slab_unoccluded_fraction(0.25, D))
    sigma = float(binomial_sigma(p, rays))
    assert abs(float(v.mean()) - (1.0 - p)) <= 5 * sigma / math.sqrt(v.size)
    # Vertices a modifier deletes have nothing baked: 0 (documented in blender/bake.py).
    group = obj.vertex_groups.new(name="Keep")
    group.add([i for i, c in enumerate(co) if c[0] < 0.1], 1.0, "REPLACE")
    mask = obj.modifiers.new("Mask", "MASK")
    mask.vertex_group = "Keep"
    bake_thickness(bpy.context, [obj], _settings(samples=rays, distance_su=D), log=_quiet)
    v = _values(mesh, "Thickness")
    assert np.all(v[co[:, 0] > 0.1] == 0.0)
    kept = interior & (co[:, 0] < -0.1)
    assert abs(float(v[kept].mean()) - (1.0 - p)) <= 5 * sigma / math.sqrt(kept.sum())


@pytest.mark.parametrize("source", ("ao", "ray"))
def test_the_mesh_is_baked_as_rendered_not_as_the_viewport_shows_it(source):
    """A cage with a Subdivision Surface modifier at 0 viewport and 2 render levels, and a
    Solidify modifier switched off in the viewport only: the bake evaluates both as the render
    does (a cube's second Catmull-Clark level has 98 vertices, twice that once solidified), and
    afterwards the modifiers are as they were."""
    mesh = _box("Cage", size=(0.4, 0.4, 0.4))
    obj = _link("Cage", mesh)
    sub = obj.modifiers.new("Subdivision", "SUBSURF")
    sub.levels, sub.render_levels = 0, 2
    solid = obj.modifiers.new("Solidify", "SOLIDIFY")
    solid.thickness, solid.show_viewport = 0.05, False
    (r,) = bake_thickness(bpy.context, [obj], _settings(source=source, samples=8, distance_su=D), log=_quiet)
    assert r.status == "baked" and r.vertices == 2 * 98, r
    assert (sub.levels, sub.render_levels, solid.show_viewport, solid.show_render) == (0, 2, False, True)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert len(obj.evaluated_get(depsgraph).data.vertices) == 8  # the viewport's cage again
    assert len(_values(mesh, "Thickness")) == 8


def test_image_target_exr_with_modifiers_saved_linked_and_described(tmp_path):
    mesh = _plane("Leaf")
    obj = _link("Leaf", mesh)
    obj.modifiers.new("Solidify", "SOLIDIFY").thickness = 0.25
    mat = bpy.data.materials.new("Leaf")
    compat.ensure_node_tree(mat)
    mesh.materials.append(mat)
    settings = _settings(
        target="image", samples=64, distance_su=D, resolution_px=32, margin_px=2, image_folder=str(tmp_path)
    )
    (r,) = bake_thickness(bpy.context, [obj], settings, log=_quiet)
    assert r.status == "baked", r.message
    assert r.filepath == str(tmp_path / "Leaf_thickness.exr") and os.path.isfile(r.filepath)
    image = bpy.data.images[r.data]
    assert tuple(image.size) == (32, 32) and image.is_float and image.colorspace_settings.name == "Non-Color"
    px = _pixels(image)
    # Texel centres with u, v in [0.25, 0.75] lie 1 (> D) inside the plane's rim.
    c = (np.arange(32) + 0.5) / 32
    inner = (c >= 0.25) & (c <= 0.75)
    v = px[np.ix_(inner, inner)][..., 0]
    p = float(slab_unoccluded_fraction(0.25, D))
    sigma = float(binomial_sigma(p, 64))
    assert np.abs(v - (1.0 - p)).max() <= 5 * sigma
    assert abs(float(v.mean()) - (1.0 - p)) <= 5 * sigma / math.sqrt(v.size)
    # The file: float32 OpenEXR holding exactly the baked pixels (rows top to bottom).
    import OpenEXR

    channels = OpenEXR.File(r.filepath).channels()
    rgb = channels["RGB"].pixels
    assert rgb.dtype == np.float32
    np.testing.assert_array_equal(rgb, px[::-1, :, :3])
    # Settings stored with the image and beside the file.
    meta = thickness_metadata(image)
    with open(r.filepath + ".json", encoding="utf-8") as f:
        sidecar = json.load(f)
    for m in (meta, sidecar):
        assert m["convention"] == "translucency" and m["distance_su"] == D and m["samples"] == 64
        assert m["uv_map"] == "UVMap" and m["modifiers"] == ["Solidify"] and m["bit_depth"] == 32
    # Linked into the material: UV Map -> Image Texture -> AOV "Thickness".
    nodes = mat.node_tree.nodes
    tex, aov = nodes[NODE_NAME], nodes[NODE_AOV]
    assert tex.image == image and aov.aov_name == "Thickness"
    assert aov.inputs["Value"].links[0].from_node == tex
    assert tex.inputs["Vector"].links[0].from_node.uv_map == "UVMap"
    # The mesh itself did not change.
    assert "Thickness" not in mesh.attributes and len(mesh.vertices) == 17 * 17


def _read_png16(path):
    """Decode an 8-bit-free, non-interlaced 16-bit RGB PNG (what Blender writes) to float."""
    data = open(path, "rb").read()
    pos, chunks = 8, {}
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        chunks.setdefault(kind, b"")
        chunks[kind] += data[pos + 8 : pos + 8 + length]
        pos += 12 + length
    w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", chunks[b"IHDR"])
    assert (depth, ctype, interlace) == (16, 2, 0)
    bpp, stride = 6, w * 6
    raw = zlib.decompress(chunks[b"IDAT"])
    out, prev = [], bytearray(stride)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1 : (y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out.append(bytes(line))
        prev = line
    return np.frombuffer(b"".join(out), dtype=">u2").reshape(h, w, 3).astype(np.float64) / 65535.0


def test_image_target_png_is_16_bit_linear(tmp_path):
    obj = _link("Block", _box("Block"))
    settings = _settings(target="image", image_format="PNG", resolution_px=16, image_folder=str(tmp_path))
    (r,) = bake_thickness(bpy.context, [obj], settings, log=_quiet)
    assert r.status == "baked" and r.filepath.endswith("Block_thickness.png")
    stored = _read_png16(r.filepath)
    px = _pixels(bpy.data.images[r.data])[::-1, :, :3]
    # 16-bit quantisation: within half a step (1/65535 / 2), plus float32 rounding.
    np.testing.assert_allclose(stored, px, atol=0.5 / 65535 + 1e-7)
    assert thickness_metadata(bpy.data.images[r.data])["bit_depth"] == 16


def test_failure_while_saving_an_image_leaves_no_image_behind(tmp_path, monkeypatch):
    obj = _link("Block", _box("Block"))

    def full_disk(image, filepath, file_format):
        open(filepath, "wb").close()  # a partial file, as a failed write leaves
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(compat, "save_float_image", full_disk)
    before = _snapshot()
    settings = _settings(target="image", resolution_px=8, image_folder=str(tmp_path))
    (r,) = bake_thickness(bpy.context, [obj], settings, log=_quiet)
    assert r.status == "failed" and "No space left on device" in r.message
    assert len(bpy.data.images) == 0 and list(tmp_path.iterdir()) == []
    assert _snapshot() == before


def test_rebake_reuses_its_image_and_attribute(tmp_path):
    obj = _link("Block", _box("Block"))
    settings = _settings(target="image", resolution_px=8, image_folder=str(tmp_path))
    first = bake_thickness(bpy.context, [obj], settings, log=_quiet)[0]
    second = bake_thickness(bpy.context, [obj], dataclasses.replace(settings, resolution_px=16), log=_quiet)[0]
    assert first.data == second.data and len(bpy.data.images) == 1
    assert tuple(bpy.data.images[second.data].size) == (16, 16)
    for _ in range(2):
        bake_thickness(bpy.context, [obj], _settings(samples=4), log=_quiet)
    assert [a.name for a in obj.data.color_attributes] == ["Thickness"]
    assert len(obj.data.materials) == 0  # nothing to link into, and no slot left behind


def test_image_target_never_overwrites_a_file_it_did_not_bake(tmp_path):
    """An image file of the same name that SSS Lab did not bake from this mesh (no sidecar, or a
    sidecar naming another mesh) stops the bake before anything runs, the file untouched; two meshes
    whose names give the same file name stop it too. A map baked from the same mesh is baked again,
    and ``overwrite`` allows the rest."""
    obj = _link("Block", _box("Block"))
    settings = _settings(target="image", resolution_px=8, image_folder=str(tmp_path))
    foreign = tmp_path / "Block_thickness.exr"
    foreign.write_bytes(b"someone else's map")
    with pytest.raises(BakeError, match=r"Block_thickness\.exr' exists and SSS Lab did not bake it from mesh 'Block'"):
        bake_thickness(bpy.context, [obj], settings, log=_quiet)
    (tmp_path / "Block_thickness.exr.json").write_text('{"mesh": "Other"}')
    with pytest.raises(BakeError, match="did not bake it"):
        bake_thickness(bpy.context, [obj], settings, log=_quiet)
    assert foreign.read_bytes() == b"someone else's map" and len(bpy.data.images) == 0
    (r,) = bake_thickness(bpy.context, [obj], dataclasses.replace(settings, overwrite=True), log=_quiet)
    assert r.status == "baked" and foreign.read_bytes() != b"someone else's map"
    (again,) = bake_thickness(bpy.context, [obj], settings, log=_quiet)  # its own map: baked again
    assert again.status == "baked"
    twins = [_link(name, _box(name)) for name in ("Rock:1", "Rock/1")]  # both clean to "Rock_1"
    with pytest.raises(BakeError, match=r"meshes 'Rock:1', 'Rock/1' would all be written to 'Rock_1_thickness\.exr'"):
        bake_thickness(bpy.context, twins, settings, log=_quiet)


# -- input that is not bakeable --------------------------------------------------------------
def test_mesh_without_uv_map_image_target_error_names_it_attribute_target_works(tmp_path):
    obj = _link("NoUV", _box("NoUV", uv=False))
    with pytest.raises(BakeError, match=r"'NoUV'.*no UV map"):
        bake_thickness(bpy.context, [obj], _settings(target="image", image_folder=str(tmp_path)), log=_quiet)
    assert list(tmp_path.iterdir()) == [] and len(bpy.data.images) == 0
    (r,) = bake_thickness(bpy.context, [obj], _settings(), log=_quiet)
    assert r.status == "baked" and "Thickness" in obj.data.color_attributes


def test_non_mesh_objects_are_skipped_and_reported(addon):
    cube = _link("Cube", _box("Cube"))
    empty = _link("Empty", None)
    cam = _link("Camera", bpy.data.cameras.new("Camera"))
    _select(empty, cube, cam, active=cube)
    results = bake_thickness(bpy.context, None, _settings(), log=_quiet)
    assert sorted((r.object, r.status) for r in results) == [
        ("Camera", "skipped"),
        ("Cube", "baked"),
        ("Empty", "skipped"),
    ]
    assert {r.object: r.message for r in results if r.status == "skipped"} == {
        "Empty": "skipped: not a mesh (EMPTY)",
        "Camera": "skipped: not a mesh (CAMERA)",
    }
    # The operator runs the same (blocking, headless) and finishes.
    assert bpy.ops.sss_lab.bake_thickness() == {"FINISHED"}


def test_empty_selection_is_a_clear_error(addon):
    _link("Cube", _box("Cube"))
    _select()
    with pytest.raises(BakeError, match="nothing to bake: no objects selected"):
        bake_thickness(bpy.context, None, _settings(), log=_quiet)
    with pytest.raises(RuntimeError, match="nothing to bake"):
        bpy.ops.sss_lab.bake_thickness()
    empty = _link("Empty", None)
    with pytest.raises(BakeError, match=r"none of the objects is a mesh: 'Empty' \(EMPTY\)"):
        bake_thickness(bpy.context, [empty], _settings(), log=_quiet)
    with pytest.raises(BakeError, match="no object named 'Nope'"):
        bake_thickness(bpy.context, ["Nope"], _settings(), log=_quiet)


def test_linked_library_data_is_a_clear_error(tmp_path):
    lib_path = str(tmp_path / "library.blend")
    mesh = _box("LibMesh")
    obj = bpy.data.objects.new("LibObject", mesh)
    bpy.data.libraries.write(lib_path, {obj})
    bpy.data.objects.remove(obj)
    bpy.data.meshes.remove(mesh)
    with bpy.data.libraries.load(lib_path, link=True) as (_src, dst):
        dst.objects = ["LibObject"]
    linked = dst.objects[0]
    bpy.context.scene.collection.objects.link(linked)
    local = _link("Local", _box("Local"))
    before = _snapshot()
    with pytest.raises(BakeError, match=r"'LibObject': object is linked from the library '.*library\.blend'"):
        bake_thickness(bpy.context, [local, linked], _settings(), log=_quiet)
    assert _snapshot() == before and "Thickness" not in local.data.attributes  # nothing was baked


def test_mesh_shared_by_two_objects_is_baked_once(addon):
    mesh = _box("Shared", cuts=1)
    mat = bpy.data.materials.new("Shared")
    compat.ensure_node_tree(mat)
    mesh.materials.append(mat)
    a, b = _link("A", mesh), _link("B", mesh)
    b.location = (3.0, 0.0, 0.0)
    c = _link("C", mesh)
    c.scale = (2.0, 1.0, 1.0)
    results = bake_thickness(bpy.context, [a, b, c], _settings(), log=_quiet)
    assert [(r.object, r.status) for r in results] == [("A", "baked"), ("B", "shared"), ("C", "shared")]
    assert "shares mesh 'Shared' with 'A'" in results[1].message and not results[1].warnings
    assert any("scale differ" in w for w in results[2].warnings)
    assert [x.name for x in mesh.color_attributes] == ["Thickness"]
    assert thickness_metadata(mesh, "Thickness")["object"] == "A"
    assert mat.node_tree.nodes[NODE_NAME].attribute_name == "Thickness"


def test_zero_area_mesh_is_skipped_with_a_reason():
    flat = bpy.data.meshes.new("Line")
    flat.from_pydata([(0, 0, 0), (1, 0, 0), (2, 0, 0)], [], [(0, 1, 2)])  # collinear: zero area
    obj = _link("Line", flat)
    cube = _link("Cube", _box("Cube"))
    before = _snapshot()
    results = bake_thickness(bpy.context, [obj, cube], _settings(), log=_quiet)
    assert [(r.object, r.status) for r in results] == [("Line", "skipped"), ("Cube", "baked")]
    assert "has no surface area" in results[0].message
    assert "Thickness" not in flat.attributes
    after = _snapshot()
    assert after == before


# -- the scene is restored -------------------------------------------------------------------
def _busy_scene():
    """A scene whose settings all differ from what a bake uses, with hidden and selected
    objects, material slots linked to data and to the object, and an active colour attribute."""
    scene = bpy.context.scene
    scene.render.engine = compat.eevee_engine()
    scene.cycles.samples = 7
    scene.cycles.use_adaptive_sampling = True
    scene.cycles.film_exposure = 1.5
    scene.cycles.bake_type = "AO"
    bake = scene.render.bake
    bake.target, bake.margin, bake.use_selected_to_active, bake.use_clear = "IMAGE_TEXTURES", 3, True, False
    mats = []
    for name in ("Red", "Blue"):
        m = bpy.data.materials.new(name)
        compat.ensure_node_tree(m)
        mats.append(m)
    objs = []
    for i in range(3):
        mesh = _box(f"M{i}", location=(3 * i, 0, 0))
        mesh.color_attributes.new("Col", "BYTE_COLOR", "CORNER")
        mesh.color_attributes.active_color_name = "Col"
        mesh.materials.append(mats[0])
        objs.append(_link(f"O{i}", mesh))
    objs[1].material_slots[0].link = "OBJECT"
    objs[1].material_slots[0].material = mats[1]
    objs[2].hide_render = True
    objs[2].hide_set(True)
    other = _link("Other", _box("Other", location=(0, 5, 0)))
    _select(other, active=other)
    return objs


def test_scene_is_restored_after_a_bake():
    objs = _busy_scene()
    before = _snapshot()
    results = bake_thickness(bpy.context, objs, _settings(samples=4), log=_quiet)
    assert [r.status for r in results] == ["baked"] * 3, [r.message for r in results]
    assert _snapshot() == before
    assert all("Thickness" in o.data.color_attributes for o in objs)


def test_cancel_restores_the_scene_and_keeps_what_was_baked():
    objs = _busy_scene()
    before = _snapshot()
    asked = []

    def cancel():
        asked.append(1)
        return len(asked) > 1  # cancel before the second object

    lines = []
    results = bake_thickness(bpy.context, objs, _settings(samples=4), cancel=cancel, log=lines.append)
    assert [r.status for r in results] == ["baked", "cancelled", "cancelled"]
    assert _snapshot() == before
    assert "Thickness" in objs[0].data.color_attributes
    assert "Thickness" not in objs[1].data.color_attributes
    assert lines[-1] == "cancelled after 1 of 3 bakes"


def test_failed_bake_restores_the_scene_and_keeps_the_previous_map(monkeypatch):
    objs = _busy_scene()
    bake_thickness(bpy.context, objs[:1], _settings(samples=4), log=_quiet)
    previous = _values(objs[0].data, "Thickness").copy()
    before = _snapshot()
    calls, real_bake = [], compat.run_bake

    def failing_bake(**kwargs):
        calls.append(kwargs)
        if len(calls) == 1:  # the first object's bake fails, the others run
            raise RuntimeError("Error: simulated Cycles failure\n")
        return real_bake(**kwargs)

    assert bake_mod.compat is compat
    monkeypatch.setattr(compat, "run_bake", failing_bake)
    results = bake_thickness(bpy.context, objs, _settings(samples=4, convention="thickness"), log=_quiet)
    assert [r.status for r in results] == ["failed", "baked", "baked"]
    assert results[0].message == "failed: simulated Cycles failure"
    assert _snapshot() == before
    np.testing.assert_array_equal(_values(objs[0].data, "Thickness"), previous)
    assert thickness_metadata(objs[0].data, "Thickness")["convention"] == "translucency"


# -- operator and command line ---------------------------------------------------------------
def test_operator_bakes_named_objects_with_the_panel_settings(addon):
    cube = _link("Cube", _box("Cube"))
    _link("Other", _box("Other", location=(3, 0, 0)))
    _select()
    s = bpy.context.scene.sss_lab.bake
    s.samples, s.convention, s.attribute_name = 4, "thickness", "Thick"
    assert bpy.ops.sss_lab.bake_thickness(objects=[{"name": "Cube"}]) == {"FINISHED"}
    assert thickness_metadata(cube.data, "Thick")["convention"] == "thickness"
    assert "Thick" not in bpy.data.objects["Other"].data.attributes
    assert "UNDO" in bpy.types.SSS_LAB_OT_bake_thickness.bl_options


def test_modal_operator_steps_on_timer_and_esc_cancels_with_the_scene_restored(modal):
    """The operator's own invoke/modal with timer and Esc events (conftest's ``modal``)."""
    objs = _busy_scene()
    bpy.context.scene.sss_lab.bake.samples = 4
    before = _snapshot()
    window = modal.Window()
    context = modal.context(window)
    names = [SimpleNamespace(name=o.name) for o in objs]
    op = modal.driver(SSS_LAB_OT_bake_thickness, objects=names)
    assert op.invoke(context, modal.event("NONE")) == {"RUNNING_MODAL"}
    assert window.progress == [("begin", 0, 3)] and _snapshot() == before  # planned, nothing changed
    assert window.status[-1] == "Thickness Bake 1/3: object 1 (Esc: cancel after this step)"
    assert op.modal(context, modal.event("MOUSEMOVE")) == {"RUNNING_MODAL"}  # held back
    assert window.progress == [("begin", 0, 3)]
    assert op.modal(context, modal.event("TIMER")) == {"RUNNING_MODAL"}
    assert window.progress[-1] == ("update", 1) and window.status[-1].startswith("Thickness Bake 2/3: object 2")
    assert op.modal(context, modal.event("ESC")) == {"FINISHED"}  # one object was baked: an undo step
    assert window.timers == [] and window.progress[-1] == ("end",) and window.status[-1] is None
    assert _snapshot() == before
    assert [level for level, _ in op.reports] == ["WARNING", "INFO", "WARNING", "WARNING"]
    assert "cancelled" in op.reports[-1][1]
    # Run to the end: one TIMER event per object.
    op = modal.driver(SSS_LAB_OT_bake_thickness, objects=names[1:])
    assert op.invoke(context, modal.event("NONE")) == {"RUNNING_MODAL"}
    assert op.modal(context, modal.event("TIMER")) == {"RUNNING_MODAL"}
    assert op.modal(context, modal.event("TIMER")) == {"FINISHED"}
    assert _snapshot() == before and all("Thickness" in o.data.color_attributes for o in objs)


def test_operator_invoked_headless_runs_blocking(addon):
    cube = _link("Cube", _box("Cube"))
    _select(cube, active=cube)
    bpy.context.scene.sss_lab.bake.samples = 4
    assert bpy.ops.sss_lab.bake_thickness("INVOKE_DEFAULT") == {"FINISHED"}
    assert "Thickness" in cube.data.color_attributes
    bpy.context.scene.sss_lab.bake.attribute_name = ""
    with pytest.raises(RuntimeError, match="attribute_name"):
        bpy.ops.sss_lab.bake_thickness()


@pytest.mark.parametrize("target", ["attribute", "image"])
def test_panel_draws_the_settings_and_the_button(addon, draw_panels, target):
    bpy.context.scene.sss_lab.bake.target = target
    drawn = [name for panel, _, name, _ in draw_panels("render") if panel == "Thickness Bake"]
    assert "sss_lab.bake_thickness" in drawn and {"samples", "distance", "only_local", "convention"} <= set(drawn)
    if target == "image":
        assert {"resolution", "margin", "image_format", "image_folder"} <= set(drawn)
        assert "Undo cannot delete image files already saved." in drawn
        assert "source" not in drawn  # the ray source measures at the vertices
        bpy.context.scene.sss_lab.bake.source = "ray"
        assert bake_mod.settings_from_scene(bpy.context.scene).source == "ao"
    else:
        assert {"attribute_name", "source"} <= set(drawn)


def _run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "sss_lab", "bake-thickness", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_cli_refuses_to_overwrite_the_input_and_writes_a_new_file(tmp_path):
    # By default the command bakes the meshes that carry a subsurface material: the cube, not the floor.
    wax = bpy.data.materials.new("Wax")
    compat.ensure_node_tree(wax)
    wax.node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 1.0
    _link("Cube", _box("Cube")).data.materials.append(wax)
    _link("Floor", _box("Floor", size=(4.0, 4.0, 0.1), location=(0.0, 0.0, -1.0)))
    src = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(src), copy=True)
    original = src.read_bytes()
    done = _run_cli(src, "--out", src, "--samples", "4")
    assert done.returncode == 2
    assert "is the input file; refusing to overwrite it (pass --overwrite" in done.stderr
    assert src.read_bytes() == original
    out = tmp_path / "baked.blend"
    done = _run_cli(src, "--out", out, "--samples", "4")
    assert done.returncode == 0, done.stderr
    assert "bake-thickness: [1/1] Cube: baked translucency attribute 'Thickness'" in done.stdout
    assert done.stdout.splitlines()[-2] == f"Saved: '{out}'"  # Blender's form, as every command prints it
    assert src.read_bytes() == original
    bpy.ops.wm.open_mainfile(filepath=str(out), load_ui=False)
    mesh = bpy.data.objects["Cube"].data
    assert "Thickness" in mesh.color_attributes and META_KEY in mesh
    assert "Thickness" not in bpy.data.objects["Floor"].data.color_attributes


def _write_fails(kind, monkeypatch):
    """Make the bake's image writes fail as ``kind`` does on a full or read-only disk."""
    import errno

    from sss_lab.core.base import files

    if kind == "sidecar on a full disk":
        write_text = files.write_text

        def full(path, text):
            if path.endswith(".exr.json"):
                raise OSError(errno.ENOSPC, "No space left on device", path)
            return write_text(path, text)

        monkeypatch.setattr(files, "write_text", full)
        return

    def save(image, filepath, file_format):
        open(filepath, "wb").close()  # a partial file, as a failed write leaves
        if kind == "Blender's saver on a full disk":  # Blender's words for it: no errno
            raise RuntimeError("Error: Could not write image: Invalid argument")
        code = {"full disk": errno.ENOSPC, "read-only disk": errno.EROFS, "no permission": errno.EACCES}[kind]
        raise OSError(code, os.strerror(code), filepath)

    monkeypatch.setattr(compat, "save_float_image", save)
    if kind == "Blender's saver on a full disk":
        monkeypatch.setattr(files, "disk_full", lambda path: True)


@pytest.mark.parametrize(
    "kind, reason",
    [
        ("full disk", "No space left on device; the disk is full"),
        ("Blender's saver on a full disk", "No space left on device; the disk is full"),
        ("sidecar on a full disk", "No space left on device; the disk is full"),
        ("read-only disk", "Read-only file system"),
        ("no permission", "Permission denied"),
    ],
)
def test_cli_image_target_on_a_full_or_read_only_disk_is_a_failed_write(tmp_path, monkeypatch, capsys, kind, reason):
    """Writing the images fails however the disk refuses them: exit 1 (a failed write, not bad
    input), the reason on stderr in one readable line per object (no Python repr), no image, no
    sidecar, no image folder and no OUT left, the input unchanged."""
    from sss_lab.addon import cli

    wax = bpy.data.materials.new("Wax")
    compat.ensure_node_tree(wax)
    wax.node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 1.0
    _link("Cube", _box("Cube")).data.materials.append(wax)
    src = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(src), copy=True)
    original = src.read_bytes()
    _write_fails(kind, monkeypatch)
    out, images = tmp_path / "out" / "baked.blend", tmp_path / "disk" / "img"
    argv = ["bake-thickness", src, "--out", out, "--target", "image", "--image-size", "8", "--samples", "2"]
    code = cli.main(list(map(str, [*argv, "--image-dir", images])))
    stdout, stderr = capsys.readouterr()
    assert code == 1, stderr
    failed = [line for line in stderr.splitlines() if "Cube: failed:" in line]
    assert len(failed) == 1 and reason in failed[0], stderr
    assert "Error(" not in stdout + stderr and "Traceback" not in stderr
    assert stderr.splitlines()[-1].startswith("sss_lab bake-thickness: error: nothing was baked (1 failed")
    assert not images.exists() and not (tmp_path / "disk").exists() and not out.exists()
    assert src.read_bytes() == original


# -- low-poly meshes ---------------------------------------------------------------------------
def _face_centre_uv(mesh, normal):
    """UV of the centre of the face of ``mesh`` whose normal is ``normal`` (the mean of its
    corners' UVs: the faces of a box are parallelograms in UV)."""
    face = next(p for p in mesh.polygons if np.allclose(tuple(p.normal), normal, atol=1e-4))
    uv = mesh.uv_layers.active.data
    return np.mean([tuple(uv[i].uv) for i in face.loop_indices], axis=0)


def test_low_poly_slabs_warn_on_vertices_and_read_the_slab_law_from_an_image(tmp_path):
    """Fins of 8-vertex boxes (5 x 9 cm, 2 to 24 mm thick) with the bake's automatic distance.
    A vertex attribute holds only the corners, which see open space: the bake says so, naming
    the mesh and the remedy. The image target resolves the faces: at the centre of the front
    face each fin reads the slab law 1 - (t / D)^2 within 0.1."""
    # Measured at 256 rays: the vertices' mean (the face centre's value) reads 0.98 / 0.96 / 0.91 /
    # 0.85 / 0.77 where the law gives 0.99 / 0.96 / 0.85 / 0.67 / 0.18; the image 0.99 / 0.97 /
    # 0.87 / 0.69 / 0.20.
    thicknesses = (0.002, 0.005, 0.01, 0.015, 0.024)
    fins = [
        _link(f"Fin {t}", _box(f"Fin {t}", size=(0.05, t, 0.09), location=(0.1 * i, 0, 0)))
        for i, t in enumerate(thicknesses)
    ]
    results = bake_thickness(bpy.context, fins, _settings(samples=64), log=_quiet)
    for r in results:
        assert r.status == "baked"
        (warning,) = [w for w in r.warnings if "too coarse" in w]
        assert f"mesh {r.mesh!r} is too coarse for a per-vertex thickness map" in warning
        assert "subdivide the mesh" in warning and "bake to an image" in warning
    settings = _settings(samples=64, target="image", resolution_px=64, image_folder=str(tmp_path))
    results = bake_thickness(bpy.context, fins, settings, log=_quiet)
    for fin, t, r in zip(fins, thicknesses, results, strict=True):
        assert r.status == "baked" and not [w for w in r.warnings if "too coarse" in w], r
        image = bpy.data.images[r.data]
        px = np.array(image.pixels[:], dtype=np.float32).reshape(image.size[1], image.size[0], 4)
        u, v = _face_centre_uv(fin.data, (0.0, -1.0, 0.0))
        value = float(px[int(v * image.size[1]), int(u * image.size[0]), 0])
        expected = 1.0 - float(slab_unoccluded_fraction(t, r.distance_su))
        # 0.1: the bound; the texel's noise (64 rays, sigma <= 0.0625) is well inside it.
        assert abs(value - expected) < 0.1, (t, value, expected, r.distance_su)


def test_subsurface_meshes_are_the_command_lines_default():
    skin = bpy.data.materials.new("Skin")
    compat.ensure_node_tree(skin)
    skin.node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 1.0
    plain = bpy.data.materials.new("Floor")
    compat.ensure_node_tree(plain)
    plain.node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 0.0
    head = _link("Head", _box("Head"))
    head.data.materials.append(skin)
    floor = _link("Floor", _box("Floor"))
    floor.data.materials.append(plain)
    _link("Bare", _box("Bare"))
    bpy.context.view_layer.update()
    assert [o.name for o in bake_mod.subsurface_meshes(bpy.context.scene)] == ["Head"]
    assert bake_mod.carries_subsurface(head) and not bake_mod.carries_subsurface(floor)
    # A Subsurface Weight linked to a texture (0 in its socket), and a scattering Principled BSDF
    # behind a Mix Shader, scatter as Cycles renders them: their meshes are baked too.
    linked = bpy.data.materials.new("Freckled")
    compat.ensure_node_tree(linked)
    nodes = linked.node_tree.nodes
    noise = nodes.new("ShaderNodeTexNoise")
    linked.node_tree.links.new(noise.outputs["Fac"], nodes["Principled BSDF"].inputs["Subsurface Weight"])
    mixed = bpy.data.materials.new("Coated")
    compat.ensure_node_tree(mixed)
    nodes = mixed.node_tree.nodes
    nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 1.0
    mix = nodes.new("ShaderNodeMixShader")
    mixed.node_tree.links.new(nodes["Principled BSDF"].outputs[0], mix.inputs[2])
    mixed.node_tree.links.new(mix.outputs[0], nodes["Material Output"].inputs["Surface"])
    for name, mat in (("Cheek", linked), ("Vase", mixed)):
        _link(name, _box(name)).data.materials.append(mat)
    bpy.context.view_layer.update()
    assert sorted(o.name for o in bake_mod.subsurface_meshes(bpy.context.scene)) == ["Cheek", "Head", "Vase"]


@pytest.mark.parametrize(
    ("rotation_deg", "location"),
    [
        ((0.0, 0.0, 15.0), (0.02, -0.01, 0.05)),
        ((20.0, 35.0, 15.0), (0.02, -0.01, 0.05)),
        ((0.0, 90.0, 45.0), (0.02, -0.01, 0.05)),
        ((20.0, 35.0, 15.0), (120.0, -40.0, 15.0)),  # far from the origin: coarser float32 coordinates
    ],
)
def test_ray_source_reads_a_turned_low_poly_slab_at_every_corner(rotation_deg, location):
    """An 8-vertex slab 14 x 3 x 10 cm turned in the world: every corner reads the slab's own law
    (3 cm). A ray from a corner along one face's normal runs in the planes of the faces beside it;
    once the box is turned, rounding made it cross them (0.5 and 1.4 cm read at the corners of the
    15-degree slab), so hits on a face whose plane holds the ray's start are passed over. Tolerance:
    the float32 map's rounding (as the fins' test)."""
    slab = _link("Turned", _box("Turned", size=(0.14, 0.03, 0.10), uv=False))
    slab.rotation_euler = [math.radians(a) for a in rotation_deg]
    slab.location = location
    bpy.context.view_layer.update()
    distance = 0.0466
    (r,) = bake_thickness(bpy.context, [slab], _settings(source="ray", distance_su=distance), log=_quiet)
    assert r.status == "baked", r
    expected = 1.0 - float(slab_unoccluded_fraction(0.03, distance))
    np.testing.assert_allclose(_values(slab.data, "Thickness"), expected, atol=1e-4)


@pytest.mark.parametrize("offset", [-1.0, 0.0, 1.0])
def test_ray_source_reads_a_solidified_sheet_as_its_shell(offset):
    """A single-sheet grid given its thickness (2.5 mm) by a Solidify modifier, turned, with the
    sheet on either side of the shell or in its middle: the map is read from the mesh as rendered.
    Each ray starts at the shell's surface nearest the vertex, so every interior vertex reads the
    shell (float32 rounding of the map); no vertex reads less than half the shell (the rim of a
    sheet in the middle of its shell: half the shell to either side) or a negative distance."""
    sheet = _link("Sheet", _plane("Sheet", width=0.12, segments=6))
    solid = sheet.modifiers.new("Solidify", "SOLIDIFY")
    solid.thickness = 0.0025
    solid.offset = offset
    sheet.rotation_euler = (math.radians(70.0), math.radians(10.0), math.radians(25.0))
    bpy.context.view_layer.update()
    distance = 0.02
    (r,) = bake_thickness(bpy.context, [sheet], _settings(source="ray", distance_su=distance), log=_quiet)
    assert r.status == "baked", r
    values = _values(sheet.data, "Thickness")
    shell = 1.0 - float(slab_unoccluded_fraction(0.0025, distance))
    half = 1.0 - float(slab_unoccluded_fraction(0.00125, distance))
    assert np.all((values >= 0.0) & (values <= half + 1e-4)), values
    co = _coords(sheet.data)
    inner = np.all(np.abs(co[:, :2]) < 0.06 - 1e-6, axis=1)
    np.testing.assert_allclose(values[inner], shell, atol=1e-4)


def test_ray_source_reads_the_slab_law_on_low_poly_fins_and_the_diameter_of_a_tube():
    """The "ray" source: the distance to the far side along the inward normals, written as the AO
    a slab of that thickness gives. Every corner of an 8-vertex fin reads the fin's own slab law
    exactly (its shortest ray crosses the fin; float32 rounding), where the AO source's corners
    see open space; a cylinder's side vertices read its diameter, where the AO source reads a
    fraction of it (docs/references.md §14). No warning about coarse meshes."""
    thicknesses = (0.002, 0.005, 0.01, 0.024)
    fins = [
        _link(f"Fin {t}", _box(f"Fin {t}", size=(0.05, t, 0.09), location=(0.1 * i, 0, 0), uv=False))
        for i, t in enumerate(thicknesses)
    ]
    results = bake_thickness(bpy.context, fins, _settings(source="ray", distance_su=0.03), log=_quiet)
    for fin, t, r in zip(fins, thicknesses, results, strict=True):
        assert r.status == "baked" and not [w for w in r.warnings if "too coarse" in w], r
        expected = 1.0 - float(slab_unoccluded_fraction(t, 0.03))
        np.testing.assert_allclose(_values(fin.data, "Thickness"), expected, atol=1e-4)
        assert thickness_metadata(fin.data)["Thickness"]["source"].startswith("distance to the far side")
    bm = bmesh.new()
    bmesh.ops.create_cone(bm, cap_ends=True, segments=32, radius1=0.01, radius2=0.01, depth=0.1)
    mesh = bpy.data.meshes.new("Tube")
    bm.to_mesh(mesh)
    bm.free()
    tube = _link("Tube", mesh)
    (r,) = bake_thickness(bpy.context, [tube], _settings(source="ray", distance_su=0.05), log=_quiet)
    assert r.status == "baked"
    co = _coords(tube.data)
    side = np.abs(co[:, 2]) < 0.05 - 1e-6
    x = 0.05 * np.sqrt(1.0 - _values(tube.data, "Thickness")[side])  # back to a length: the slab law
    # The diameter within the polygon's flattening (cos(pi / 32) of the circle: 0.5 %).
    np.testing.assert_allclose(x, 0.02, rtol=0.01)
    with pytest.raises(ValueError, match="bake source 'ray' measures the thickness at the mesh's vertices"):
        _settings(source="ray", target="image")
