"""Ground truth: each technique against Cycles random walk on the sample scenes (marked slow,
run in CI), the reference cache, the report's numbers, and bad input.

Settings are small so that CI stays fast: 96 x 96 pixels, a 128-sample reference (seed 0), passes
at 16 samples, one quality per technique, no Cycles peers.

Margins: a technique meant for a scene must cut the no-SSS image's relative RMSE (over the
subsurface pixels, 2 x 2 box-downsampled) to at most ``MARGIN`` of it. The reference itself is
noisy: its noise floor (the same render with another seed, reported as ``noise_floor``) is about
0.05 to 0.08 relative RMSE at these settings, and it is in both errors alike, so a technique
can never reach 0; the margins below leave room for that floor while still demanding that the
technique remove a clear share of the error the missing SSS causes. The figures behind them
are in the comparison report of each scene (README, "Comparison").
"""

import dataclasses
import json
import os
import re

import bpy
import numpy as np
import pytest

from sss_lab.blender import compare as compare_mod
from sss_lab.blender import compat, reference_cache
from sss_lab.blender.compare import CompareSettings, compare
from sss_lab.blender.reference_cache import cached_reference
from sss_lab.blender.samples import load_sample_scenes
from sss_lab.core.pipeline import apply as core_apply
from sss_lab.core.pipeline import mapping
from sss_lab.core.scene import exr
from sss_lab.core.techniques.registry import TECHNIQUES

pytestmark = pytest.mark.slow

QUALITIES = {"sta": ({},), "ssss": ({"n_taps": 17},), "burley": ({"n_samples": 32},)}
# (scene, technique, margin): the techniques each scene is meant for.
CASES = (
    ("head_frontlit", "ssss", 0.8),
    ("head_frontlit", "burley", 0.8),
    ("wax_marble", "ssss", 0.8),
    ("wax_marble", "burley", 0.8),
    ("backlit_thin", "sta", 0.6),
    ("depth_leak", "ssss", 0.9),
    ("depth_leak", "burley", 0.9),
)


def _settings(**kw):
    base = dict(
        resolution=(96, 96),
        reference_samples=128,
        pass_samples=16,
        peer_samples=(),
        cycles_burley=False,
        qualities=QUALITIES,
        eevee=False,  # EEVEE has its own test: software OpenGL takes seconds a frame
    )
    base.update(kw)
    return CompareSettings(**base)


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    """The sample scenes, built once for the module (the build bakes thickness)."""
    folder = tmp_path_factory.mktemp("scenes")
    scenes = load_sample_scenes()
    out = {}
    for name in sorted({c[0] for c in CASES}):
        out[name] = scenes.build(name, str(folder / f"{name}.blend"))
    return out


def _open(path):
    bpy.ops.wm.open_mainfile(filepath=path)
    return bpy.context.scene


@pytest.fixture(scope="module")
def reports(blends, tmp_path_factory):
    """One comparison per scene with the techniques its cases name."""
    folder = tmp_path_factory.mktemp("reports")
    out = {}
    for name, path in blends.items():
        techniques = tuple(sorted({t for s, t, _ in CASES if s == name}))
        scene = _open(path)
        out[name] = compare(scene, str(folder / name), _settings(techniques=techniques), log=None or (lambda s: None))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return out, folder


@pytest.mark.parametrize(("scene", "technique", "margin"), CASES)
def test_technique_beats_no_sss_on_its_scene(reports, scene, technique, margin):
    data = reports[0][scene]
    assert data["complete"], data["notes"]
    by_name = {e["name"]: e for e in data["entries"]}
    base = by_name["no SSS"]["metrics"]["rel_rmse"]
    entry = next(e for e in data["entries"] if e.get("technique") == technique)
    err = entry["metrics"]["rel_rmse"]
    noise = data["noise_floor"]["rel_rmse"]
    print(f"{scene} {technique}: rel. RMSE {err:.4f} vs no SSS {base:.4f} (noise floor {noise:.4f})")
    assert err <= margin * base


def test_report_numbers_are_the_json_numbers(reports):
    folder = reports[1]
    for name in reports[0]:
        with open(os.path.join(folder, name, "metrics.json"), encoding="utf-8") as fh:
            data = json.load(fh)
        with open(os.path.join(folder, name, "report.md"), encoding="utf-8") as fh:
            md = fh.read()
        html = open(os.path.join(folder, name, "report.html"), encoding="utf-8").read()
        for entry in data["entries"]:
            cell = r" \| ([^|]+)"
            row = re.search(r"^\| " + re.escape(entry["name"]) + r" \| [^|]+" + cell * 5 + r" \|", md, re.M)
            assert row, entry["name"]
            keys = ("rel_rmse", "bias", "pass_noise", "rmse", "ssim")
            m = entry["metrics"]
            if entry["kind"] == "cycles" and "OIDN" not in entry["name"]:  # no passes, no second seed to split by
                assert row.group(2).strip() == row.group(3).strip() == "—"
                keys = ("rel_rmse", "rmse", "ssim")
                shown = [float(row.group(i)) for i in (1, 4, 5)]
            else:
                # The error is split into bias and pass noise, which add in quadrature.
                assert m["bias"] ** 2 + m["pass_noise"] ** 2 == pytest.approx(m["rel_rmse"] ** 2, rel=1e-6)
                shown = [float(v) for v in row.groups()]
            for s, e in zip(shown, [m[k] for k in keys], strict=True):
                assert s == pytest.approx(e, rel=5e-4)  # the table shows 4 significant digits
            assert entry["name"] in html
        # Two costs: each technique's SSS effect alone (its apply) and end to end (passes + apply).
        costs = data["costs"]
        # Cycles random walk at the passes' samples is rendered even without peers: its SSS effect
        # is that render minus the passes' (Cycles without SSS at the same samples).
        rw = next(e for e in data["entries"] if e["name"] == f"Cycles {costs['samples']} spp")
        assert costs["cycles_random_walk_s"] == rw["time_s"]["total"] > 0
        assert costs["cycles_sss_effect_s"] == pytest.approx(rw["time_s"]["total"] - costs["cycles_without_sss_s"])
        for row in costs["techniques"]:
            entry = next(e for e in data["entries"] if e["name"] == row["name"])
            assert row["sss_effect_s"] == entry["time_s"]["apply"] < row["end_to_end_s"] == entry["time_s"]["total"]
        assert "## Two costs" in md
        # The machine-independent axis: a technique's samples per pixel from its quality, a render's samples.
        lights = data["scene"]["lights"]
        for entry in data["entries"]:
            if entry["kind"] == "technique":
                spec = TECHNIQUES[entry["technique"]]
                assert entry["samples_per_pixel"] == spec.samples_per_pixel(entry["quality"], lights), entry
            elif entry["kind"] == "cycles":
                assert entry["samples_per_pixel"] == int(re.search(r"(\d+) spp", entry["name"]).group(1))
            else:
                assert "samples_per_pixel" not in entry
        for f in ("grid.png", "pareto.svg", "pareto_samples.svg"):
            assert os.path.getsize(os.path.join(folder, name, f)) > 0


def test_report_pages_open_in_a_browser(reports, report_page):
    """The real comparisons' report pages in headless Chromium: every picture loads, the plot
    draws every measured entry, no console error, readable at phone and desktop widths."""
    folder = reports[1]
    for name in reports[0]:
        where = os.path.join(folder, name)
        assert report_page.problems(where, report_page.inspect(where)) == [], name


def test_reference_cache_is_reused_and_invalidated_when_the_scene_changes(blends, tmp_path):
    scene = _open(blends["head_frontlit"])
    kw = dict(samples=4, seed=0, resolution=(32, 32), method=None, log=lambda s: None)
    first, _, cached = cached_reference(scene, str(tmp_path), **kw)
    assert not cached
    again, _, cached = cached_reference(scene, str(tmp_path), **kw)
    assert cached and (again == first).all()
    light = next(o for o in scene.objects if o.type == "LIGHT")
    light.data.energy *= 2
    _, _, cached = cached_reference(scene, str(tmp_path), **kw)
    assert not cached  # a changed light is a new reference
    light.data.energy /= 2
    _, _, cached = cached_reference(scene, str(tmp_path), **kw)
    assert cached  # back as it was: the first one again
    _, _, cached = cached_reference(scene, str(tmp_path), **{**kw, "samples": 5})
    assert not cached  # other settings, another reference


def _snapshot(scene):
    mats = {}
    for mat in bpy.data.materials:
        if mat.node_tree is None:
            continue
        for node in mat.node_tree.nodes:
            if node.bl_idname == "ShaderNodeBsdfPrincipled":
                mats[mat.name] = (
                    node.subsurface_method,
                    node.inputs["Subsurface Weight"].default_value,
                    mat.pass_index,
                )
    r, c = scene.render, scene.cycles
    return (
        mats,
        r.resolution_x,
        r.resolution_y,
        r.resolution_percentage,
        r.image_settings.file_format,
        r.image_settings.color_depth,
        c.samples,
        c.seed,
        c.use_adaptive_sampling,
        tuple(o.pass_index for o in scene.objects),
        r.engine,
        r.use_compositing,
        scene.eevee.taa_render_samples,
        sum(len(m.node_tree.links) for m in bpy.data.materials if m.node_tree is not None),
    )


def test_scene_is_unchanged_and_bad_input_is_refused(blends, tmp_path, monkeypatch):
    scene = _open(blends["head_frontlit"])
    before = _snapshot(scene)
    # A subsurface method the mapping does not know: the techniques are noted, the report says
    # it is incomplete (and the scene is left as it was).
    method = compat.random_walk_method()  # the sample scenes' method in this Blender
    monkeypatch.setattr(mapping, "MAPPINGS", {k: v for k, v in mapping.MAPPINGS.items() if k != method})
    data = compare(
        scene,
        str(tmp_path / "unknown"),
        _settings(resolution=(32, 32), reference_samples=4, pass_samples=2, techniques=("burley",)),
        log=lambda s: None,
    )
    assert not data["complete"]
    assert any(method in n for n in data["notes"])
    with open(tmp_path / "unknown" / "metrics.json", encoding="utf-8") as fh:
        assert json.load(fh)["complete"] is False
    monkeypatch.undo()
    assert _snapshot(scene) == before
    # No camera.
    cam = scene.camera
    scene.camera = None
    with pytest.raises(ValueError, match="no active camera"):
        compare(scene, str(tmp_path / "nocam"), _settings())
    scene.camera = cam
    # No subsurface material.
    for mat in bpy.data.materials:
        if mat.node_tree is not None:
            for node in mat.node_tree.nodes:
                if node.bl_idname == "ShaderNodeBsdfPrincipled":
                    node.inputs["Subsurface Weight"].default_value = 0.0
    with pytest.raises(ValueError, match="no material with subsurface scattering"):
        compare(scene, str(tmp_path / "nosss"), _settings())
    assert not os.path.exists(tmp_path / "nosss" / "metrics.json")
    assert compare_mod.CompareSettings  # the module's public entry points are importable


def test_compare_operator_writes_the_report_and_leaves_the_scene(addon, blends, tmp_path):
    scene = _open(blends["head_frontlit"])
    scene.render.resolution_x = scene.render.resolution_y = 32  # small and quick; the operator keeps the scene's
    scene.eevee.taa_render_samples = 4  # the scene's own EEVEE setting, which the comparison uses
    before = _snapshot(scene)
    result = bpy.ops.sss_lab.compare(directory=str(tmp_path), reference_samples=4, pass_samples=2)
    assert result == {"FINISHED"}
    with open(tmp_path / "metrics.json", encoding="utf-8") as fh:
        data = json.load(fh)
    assert data["settings"]["resolution"] == [32, 32]
    ran = {e["technique"] for e in data["entries"] if e["kind"] == "technique"}
    assert ran == {"sta", "ssss", "burley", "combined"}
    # The panel's Compare includes EEVEE by default (here EGL makes its context headless).
    assert [e["name"] for e in data["entries"] if e["kind"] == "eevee"] == [
        "EEVEE 4 samples",
        "EEVEE 4 samples, SSS effect",
    ]
    assert os.path.isfile(tmp_path / "report.html")
    assert _snapshot(scene) == before
    # A relative folder of an unsaved file cannot be resolved: refused, nothing written.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with pytest.raises(RuntimeError, match="Save the .blend file first"):
        bpy.ops.sss_lab.compare(directory="//report/")


def test_eevee_is_scored_on_its_image_and_on_its_sss_effect(blends, tmp_path):
    """EEVEE rendered with and without scattering: its image against the reference, and Cycles'
    image without scattering plus EEVEE's difference scored the same way; cached like the Cycles
    images; the scene left as it was."""
    from sss_lab.blender.eevee import cached_eevee
    from sss_lab.blender.reference_cache import scene_fingerprint
    from sss_lab.core.study import metrics

    scene = _open(blends["head_frontlit"])
    before = _snapshot(scene)
    settings = _settings(resolution=(32, 32), reference_samples=4, pass_samples=2, techniques=("burley",))
    settings = dataclasses.replace(settings, eevee=True, eevee_samples=2)
    lines = []
    data = compare(scene, str(tmp_path), settings, log=lines.append)
    assert _snapshot(scene) == before
    assert data["complete"] and data["eevee"]["samples"] == 2 and "error" not in data["eevee"]
    rows = {e["name"]: e for e in data["entries"] if e["kind"] == "eevee"}
    assert list(rows) == ["EEVEE 2 samples", "EEVEE 2 samples, SSS effect"]
    # From the cache now: the images the rows were scored on.
    cache = str(tmp_path / "cache")
    fp = scene_fingerprint(scene)
    on, _, cached_on = cached_eevee(scene, cache, samples=2, resolution=(32, 32), sss=True, fingerprint=fp, log=None)
    off, _, cached_off = cached_eevee(scene, cache, samples=2, resolution=(32, 32), sss=False, fingerprint=fp, log=None)
    assert cached_on and cached_off and not np.array_equal(on, off)  # scattering changes EEVEE's picture
    passes = exr.read_passes(str(tmp_path / "passes" / "passes_0001.exr"))
    ref, _, _ = cached_reference(scene, cache, samples=4, seed=0, resolution=(32, 32), method=None, log=lambda _s: None)
    mask = core_apply.index_map(passes) >= 1
    effect = np.array(passes["Combined"], np.float32)
    effect[..., :3] += on[..., :3] - off[..., :3]
    # The same arrays and the same metric: equal to the float.
    expected = metrics.compare_images(effect, ref, mask, box=settings.box)["rel_rmse"]
    assert rows["EEVEE 2 samples, SSS effect"]["metrics"]["rel_rmse"] == expected
    assert rows["EEVEE 2 samples"]["metrics"]["rel_rmse"] == metrics.compare_images(on, ref, mask, box=2)["rel_rmse"]
    timed = rows["EEVEE 2 samples, SSS effect"]["time_s"]
    assert timed["apply"] is None and timed["sss_effect"] >= 0
    report = (tmp_path / "report.md").read_text(encoding="utf-8")
    assert "EEVEE 2 samples, SSS effect" in report


def test_without_an_opengl_context_eevee_is_left_out_with_one_line(blends, tmp_path, monkeypatch):
    from sss_lab.blender import eevee

    def no_context(*args, **kw):
        raise eevee.EeveeUnavailable("EEVEE could not render here (no OpenGL context)")

    monkeypatch.setattr(eevee, "render_eevee", no_context)
    scene = _open(blends["head_frontlit"])
    settings = _settings(resolution=(32, 32), reference_samples=4, pass_samples=2, techniques=("burley",))
    lines = []
    data = compare(scene, str(tmp_path), dataclasses.replace(settings, eevee=True), log=lines.append)
    assert data["complete"] and data["eevee"]["error"].startswith("EEVEE could not render here")
    assert not [e for e in data["entries"] if e["kind"] == "eevee"]
    assert [line for line in lines if "EEVEE is left out" in line] == [
        "note: EEVEE could not render here (no OpenGL context); EEVEE is left out of the comparison"
    ]


def _mesh(faces, verts):
    mesh = bpy.data.meshes.new("Grid")
    mesh.from_pydata(verts, [], faces)
    return mesh


def test_fingerprint_ignores_face_order_but_not_geometry():
    verts = [(x, y, 0.0) for y in range(3) for x in range(3)]
    faces = [(0, 1, 4, 3), (1, 2, 5, 4), (3, 4, 7, 6), (4, 5, 8, 7)]
    obj = bpy.data.objects.new("Grid", _mesh(faces, verts))
    scene = bpy.context.scene
    scene.collection.objects.link(obj)
    first = reference_cache.scene_fingerprint(scene)
    # The same faces listed in another order, each starting at another corner (as modifiers and
    # mesh builders may produce from run to run): the same scene, the same reference.
    original = obj.data
    obj.data = _mesh([f[1:] + f[:1] for f in reversed(faces)], verts)
    assert reference_cache.scene_fingerprint(scene) == first
    moved = list(verts)
    moved[4] = (1.0, 1.0, 0.25)
    obj.data = _mesh(faces, moved)
    assert reference_cache.scene_fingerprint(scene) != first
    obj.data = original
    assert reference_cache.scene_fingerprint(scene) == first


def test_calibration_renders_a_reference_per_extra_method(blends, tmp_path):
    scene = _open(blends["head_frontlit"])
    settings = _settings(
        resolution=(32, 32), reference_samples=4, pass_samples=2, techniques=("burley",), calibrate_methods=("BURLEY",)
    )
    data = compare(scene, str(tmp_path), settings, log=lambda s: None)
    rows = [r for r in data["calibration"]["rows"] if r["method"] == "BURLEY"]
    assert {r["mapping"] for r in rows if r["technique"] == "burley"} == set(mapping.MAPPINGS["BURLEY"])
    assert any(r["technique"] == "no SSS" for r in rows)
    # The scene's own method is calibrated against the main reference, as before.
    assert any(r["method"] == compat.random_walk_method() for r in data["calibration"]["rows"])
    # The materials are back to Random Walk afterwards.
    for mat in bpy.data.materials:
        for node in mat.node_tree.nodes if mat.node_tree else ():
            if node.bl_idname == "ShaderNodeBsdfPrincipled":
                assert compat.subsurface_method(node) == compat.random_walk_method()
    with pytest.raises(ValueError, match="calibrate_methods: unknown subsurface method 'CUBIC'"):
        compare(scene, str(tmp_path / "bad"), _settings(calibrate_methods=("CUBIC",)))


def test_scene_description_carries_the_thickness_bake_distance(blends):
    from sss_lab.blender.describe import sss_materials

    scene = _open(blends["backlit_thin"])
    by_name = {m.name: m for m in sss_materials(scene)}
    for obj in scene.objects:
        meta = obj.data.get("sss_lab_thickness") if obj.type == "MESH" else None
        if meta is None:
            continue
        distance = max(v["distance_su"] for v in meta.to_dict().values())
        for slot in obj.material_slots:
            if slot.material and slot.material.name in by_name:
                assert by_name[slot.material.name].thickness_distance >= distance > 0


def test_a_scene_without_thickness_map_is_compared_without_sta_and_says_so(tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=False)  # the default cube, camera and light
    scene = bpy.context.scene
    mat = bpy.data.materials.new("Wax")
    compat.ensure_node_tree(mat)
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    node.inputs["Subsurface Weight"].default_value = 1.0
    node.inputs["Subsurface Scale"].default_value = 0.1
    cube = bpy.data.objects["Cube"]
    cube.data.materials.clear()
    cube.data.materials.append(mat)
    scene.render.engine = compat.eevee_engine()
    data = compare(scene, str(tmp_path), _settings(resolution=(32, 24), reference_samples=4, pass_samples=2))
    assert not data["complete"]
    assert any(n.startswith("STA not run:") and "bake thickness first" in n for n in data["notes"])
    kinds = {e.get("technique") for e in data["entries"] if e["kind"] == "technique"}
    assert kinds == {"ssss", "burley"}
    assert scene.render.engine == compat.eevee_engine()  # the scene is left as it was
    with open(tmp_path / "report.md", encoding="utf-8") as fh:
        assert "This report is incomplete" in fh.read()
    # STA alone cannot run at all: a clear error, no report.
    with pytest.raises(ValueError, match="bake thickness first"):
        compare(scene, str(tmp_path / "sta"), _settings(techniques=("sta",)))
    assert not os.path.exists(tmp_path / "sta" / "metrics.json")
