"""The compiled kernels (each owner's _kernels.py on core/compute/jit.py) and their switch (core/compute/backend.py):
the check mode
really compares, Numba's absence falls back to NumPy with one line, the cache is outside the
package, and the kernels keep the reference's results on the benchmark's scene."""

import math
import os
import subprocess
import sys

import numpy as np
import pytest

import sss_lab
from sss_lab.core.compute import backend
from sss_lab.core.optics import kernels
from sss_lab.core.study.synthetic import sphere_scene
from sss_lab.core.techniques.burley.technique import burley
from sss_lab.core.techniques.ssss.technique import ssss
from sss_lab.core.techniques.sta.technique import sta

ROOT = os.path.dirname(os.path.abspath(sss_lab.__file__))


def _scene(w=96, h=64):
    passes, scene = sphere_scene(w, h)
    albedo = passes["Diffuse Color"]
    albedo[albedo.sum(axis=2) == 0] = 0.5
    normal = passes["Normal"].copy()
    normal[np.linalg.norm(normal, axis=2) == 0] = (0.0, 0.0, 1.0)
    return passes, scene, albedo, normal


def test_numba_loads_here():
    # requirements.txt installs Numba: on this set-up the compiled kernels must be the default.
    assert backend.compiled() is not None, backend.unavailable_reason()
    with backend.use("numba"):
        assert backend.active() == "numba"


@pytest.mark.parametrize("rotation", (False, True))
@pytest.mark.parametrize("mode", ("post", "pre-post"))
def test_scene_with_masks_rotation_and_ids_matches_the_reference(rotation, mode):
    # The autouse fixture runs each call on both backends and compares them.
    passes, scene, albedo, normal = _scene()
    diffuse = passes["Diffuse Direct"] + passes["Diffuse Indirect"]
    depth = passes["Depth"]
    mask = passes["Material Index"] > 0
    d = (0.04, 0.016, 0.008)
    out = burley(
        diffuse=diffuse, albedo=albedo, depth=depth, mask=mask, camera=scene.camera, d_su=d,
        object_id=passes["Object Index"], random_rotation=rotation, seed=3, albedo_mode=mode,
    )  # fmt: skip
    assert np.isfinite(out).all()
    kernel = kernels.preintegrated_kernel(17, d_su=d)
    ssss(diffuse=diffuse, albedo=albedo, depth=depth, mask=mask, camera=scene.camera, kernel=kernel, albedo_mode=mode)
    sta(
        albedo=albedo, normal=normal, position=passes["Position"], thickness=passes["Thickness"], mask=mask,
        camera=scene.camera, lights=scene.lights, power=3.0 if rotation else 2.0, falloff="map",
    )  # fmt: skip


@pytest.mark.parametrize("d_su", (0.004, 0.2))
def test_ssss_taps_read_by_runs_and_pixel_by_pixel_match_the_reference(d_su):
    # The kernel reads a tap over runs of pixels with one shift, or one pixel at a time where
    # the runs are short (SHORT_RUNS). Along the rows (all wider than SHORT_RUNS here: the plane
    # is on the mask) the narrow kernel's outermost tap has long runs on every row, the wide
    # one's short runs on some (the reference's tap positions below); the autouse fixture
    # compares each call with the NumPy reference.
    short = backend.kernels("sss_lab.core.techniques.ssss").SHORT_RUNS
    passes, scene, albedo, _ = _scene(192, 128)
    diffuse = passes["Diffuse Direct"] + passes["Diffuse Indirect"]
    depth, mask = passes["Depth"], passes["Material Index"] > 0
    kernel = kernels.preintegrated_kernel(17, d_su=(d_su, d_su / 2, d_su / 4))
    runs_short = []
    for y in range(depth.shape[0]):
        xs = np.flatnonzero(mask[y])
        if xs.size < 2:
            continue
        x0, x1 = xs[0], xs[-1]  # rows narrower than a chunk: one chunk each
        s0, s1 = scene.camera.pixels_per_unit(depth[y, [x0, x1]])
        o = np.float32(kernel.offsets_su.max())
        shift = np.floor(np.array([s0 * o + x0, s1 * o + x1], np.float32)) - (x0, x1)
        runs_short.append(x1 - x0 + 1 < short * (1 + abs(shift[1] - shift[0])))
    assert any(runs_short) == (d_su > 0.1) and not all(runs_short)
    for weighting in ("surface", "screen"):
        out = ssss(
            diffuse=diffuse, albedo=albedo, depth=depth, mask=mask, camera=scene.camera, kernel=kernel,
            weighting=weighting,
        )  # fmt: skip
        assert np.isfinite(out).all()


def test_check_mode_catches_a_kernel_that_differs(monkeypatch):
    passes, scene, albedo, _ = _scene(32, 24)
    diffuse = passes["Diffuse Direct"] + passes["Diffuse Indirect"]
    kw = dict(
        diffuse=diffuse, albedo=albedo, depth=passes["Depth"], mask=passes["Material Index"] > 0, camera=scene.camera
    )
    module = backend.kernels("sss_lab.core.techniques.burley")
    original = module.burley_kernel

    def off_by_a_little(*args):
        original(*args)
        args[-1][...] *= np.float32(1.0001)  # 1e-4 relative: far above the float32 bound

    monkeypatch.setattr(module, "burley_kernel", off_by_a_little)
    with pytest.raises(backend.BackendMismatch, match="burley: compiled result differs"):
        burley(d_su=(0.04, 0.016, 0.008), **kw)


def test_without_numba_numpy_runs_and_one_line_says_so():
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('numba', 'llvmlite'):\n"
        "            raise ImportError('blocked ' + name)\n"
        "sys.meta_path.insert(0, Block())\n"
        "import numpy as np\n"
        "from sss_lab.core.compute import backend\n"
        "from sss_lab.core.scene.scene import Camera\n"
        "from sss_lab.core.techniques.burley.technique import burley\n"
        "e = np.ones((8, 8, 3), np.float32)\n"
        "out = burley(diffuse=e, albedo=e, depth=np.full((8, 8), 2.0, np.float32), mask=np.ones((8, 8), bool),\n"
        "             camera=Camera(type='ORTHO', width_px=8, height_px=8, ortho_scale=8.0), d_su=(1.0, 1.0, 1.0))\n"
        "burley(diffuse=e, albedo=e, depth=np.full((8, 8), 2.0, np.float32), mask=np.ones((8, 8), bool),\n"
        "       camera=Camera(type='ORTHO', width_px=8, height_px=8, ortho_scale=8.0), d_su=(1.0, 1.0, 1.0))\n"
        "print(backend.active(), float(out.mean()))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split()[0] == "numpy" and float(proc.stdout.split()[1]) == pytest.approx(1.0, abs=1e-6)
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Numba cannot load" in lines[0] and "NumPy" in lines[0], proc.stderr


def test_the_cache_is_written_outside_the_package(tmp_path):
    code = (
        "import numpy as np\n"
        "from sss_lab.core.compute import backend\n"
        f"backend.set_cache_dir({str(tmp_path)!r})\n"
        "from sss_lab.core.scene.scene import Camera\n"
        "from sss_lab.core.techniques.ssss.technique import ssss\n"
        "e = np.ones((8, 8, 3), np.float32)\n"
        "with backend.use('numba'):\n"
        "    ssss(diffuse=e, albedo=e, depth=np.full((8, 8), 2.0, np.float32), mask=np.ones((8, 8), bool),\n"
        "         camera=Camera(type='ORTHO', width_px=8, height_px=8, ortho_scale=8.0), d_su=(1.0, 1.0, 1.0))\n"
        "print(sorted(backend.first_call_seconds()))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "ssss_kernel" in proc.stdout
    cached = [name for _, _, files in os.walk(tmp_path) for name in files]
    assert any(name.startswith("_kernels.ssss_kernel") and name.endswith(".nbi") for name in cached), cached
    in_package = [
        n for _, _, files in os.walk(os.path.join(ROOT, "core")) for n in files if n.endswith((".nbi", ".nbc"))
    ]
    assert in_package == []


def test_one_cache_folder_serves_the_package_under_two_names(tmp_path):
    # The same files imported as ``sss_x`` and as ``pkgs.sss_x`` (a script and the extension in
    # Blender, ``bl_ext.<repo>.sss_lab``) with one cache folder: Numba keys its entries by the
    # file's path, but they refer to the module by name. The second process, where the first
    # name cannot be imported, must compile its own rather than load the first one's.
    pkgs = tmp_path / "pkgs"
    pkgs.mkdir()
    os.symlink(ROOT, pkgs / "sss_x", target_is_directory=True)
    cache = tmp_path / "cache"
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in sys.argv[3].split(','):\n"
        "            raise ModuleNotFoundError(f'{name} may not be imported here')\n"
        "sys.meta_path.insert(0, Block())\n"
        "sys.path.insert(0, sys.argv[1])\n"
        "import importlib\n"
        "backend = importlib.import_module(sys.argv[2] + '.core.compute.backend')\n"
        f"backend.set_cache_dir({str(cache)!r})\n"
        "module = backend.compiled()\n"
        "assert module is not None, backend.unavailable_reason()\n"
        "import numpy as np\n"
        "print(module.__name__, float(module.fast_exp(np.float32(-0.5))), backend.kernel_cache_dir())\n"
    )
    runs = [(str(pkgs), "sss_x", "sss_lab,pkgs"), (str(tmp_path), "pkgs.sss_x", "sss_lab,sss_x")]
    folders = []
    for path, name, blocked in runs:
        proc = subprocess.run([sys.executable, "-c", code, path, name, blocked], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr[-3000:]
        module, value, folder = proc.stdout.split()
        # fast_exp is within 1 unit in the last place of float32 (its docstring): 2^-23 relative.
        assert module == name + ".core.compute.jit" and float(value) == pytest.approx(math.exp(-0.5), rel=2.0**-23)
        folders.append(folder)
    assert folders[0] != folders[1] and all(os.path.dirname(f) == str(cache) for f in folders)


def test_unknown_backend_names_the_value(monkeypatch):
    with pytest.raises(ValueError, match="backend: 'gpu' is not one of numba, numpy, check"):
        backend.set_backend("gpu")
    monkeypatch.setenv(backend.ENV, "fast")
    with backend.use("numba"):
        assert backend.requested() == "numba"  # an explicit choice wins over the environment
    backend.set_backend(None)
    try:
        with pytest.raises(ValueError, match="SSS_LAB_BACKEND: 'fast' is not one of"):
            backend.requested()
    finally:
        backend.set_backend(None)


def test_object_extent_is_group_extents_for_one_group():
    # The lean extent (no index arrays, for the memory of 4K frames) equals the indexed one.
    from sss_lab.core.scene.extent import group_extents, object_extent

    rng = np.random.default_rng(5)
    for _ in range(5):
        ok = rng.random((37, 53)) < rng.uniform(0.01, 0.5)
        scale = rng.uniform(10.0, 200.0, ok.shape).astype(np.float32)
        ((_, extent),) = group_extents(ok, scale)
        assert object_extent(ok, scale) == extent


@pytest.mark.parametrize("power", (0.0, 1.0, 2.0, 3.5))
def test_sta_every_kind_of_light_and_power_matches_the_reference(power):
    # The kernel runs one loop per kind of light and per power (no pow for 0, 1 and 2): each
    # against the reference, with grey and coloured lights mixed, and every falloff.
    from sss_lab.core.scene.scene import Light

    passes, scene, albedo, normal = _scene(40, 30)
    above = (1, 0, 0, 0.2, 0, 1, 0, -0.1, 0, 0, 1, 3.0, 0, 0, 0, 1)
    lights = [
        Light(
            type="SUN",
            energy=2.0,
            color=(1.0, 0.5, 0.25),
            matrix_world=(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1),
        ),
        Light(type="POINT", energy=50.0, matrix_world=above),
        Light(type="SPOT", energy=80.0, color=(0.2, 0.9, 0.4), spot_blend=0.5, matrix_world=above),
        Light(type="SPOT", energy=80.0, spot_blend=0.0, matrix_world=above),
        Light(type="AREA", energy=30.0, color=(0.7, 0.7, 0.7), matrix_world=above),
    ]
    kw = dict(
        albedo=albedo, normal=normal, position=passes["Position"], thickness=passes["Thickness"],
        mask=passes["Material Index"] > 0, camera=scene.camera, lights=lights, power=power, ambient=0.1,
    )  # fmt: skip
    assert np.isfinite(sta(falloff="map", **kw)).all()
    sta(falloff="medium", mfp_su=(0.03, 0.01, 0.005), thickness_distance_su=0.1, subsurface_method="RANDOM_WALK", **kw)
    sta(falloff="burley", d_su=(0.04, 0.016, 0.0), thickness_distance_su=0.1, thickness_convention="thickness", **kw)


@pytest.mark.parametrize("seed", (-7, 2**40 + 3))
def test_burley_rotation_of_any_seed_matches_the_reference(seed):
    # The compiled kernel hashes the pixel index with the seed's low 32 bits, as the reference does.
    passes, scene, albedo, _ = _scene(40, 30)
    burley(
        diffuse=passes["Diffuse Direct"] + passes["Diffuse Indirect"], albedo=albedo, depth=passes["Depth"],
        mask=passes["Material Index"] > 0, camera=scene.camera, d_su=(0.04, 0.016, 0.008), seed=seed,
    )  # fmt: skip


def test_burley_tiles_and_bands_match_the_reference(monkeypatch):
    # The compiled gather works on tiles of 64 rows x 128 columns within bands of rows (each
    # band with its own rotation and its packed copy of the rows its samples reach): a frame
    # wider than a tile, cut into bands of 16 rows here, against the reference, with object ids
    # (whole packed rows) and the clean-up's margins across tiles and bands; then without ids
    # on a mask away from the frame's edges (packed columns around the mask only).
    from sss_lab.core.techniques.burley import technique as burley_module

    monkeypatch.setattr(burley_module, "_BAND_ROWS", 16)
    passes, scene, albedo, _ = _scene(300, 40)
    out = burley(
        diffuse=passes["Diffuse Direct"] + passes["Diffuse Indirect"], albedo=albedo, depth=passes["Depth"],
        mask=passes["Material Index"] > 0, camera=scene.camera, d_su=(0.2, 0.08, 0.04),
        object_id=passes["Object Index"], seed=11,
    )  # fmt: skip
    assert np.isfinite(out).all()
    inner = np.zeros((40, 300), bool)
    inner[5:33, 140:290] = True
    out = burley(
        diffuse=passes["Diffuse Direct"] + passes["Diffuse Indirect"], albedo=albedo, depth=passes["Depth"],
        mask=inner & (passes["Material Index"] > 0), camera=scene.camera, d_su=(0.2, 0.08, 0.04), seed=11,
    )  # fmt: skip
    assert np.isfinite(out).all()


def test_burley_bands_reuse_the_rows_they_share(monkeypatch):
    # Each band of the compiled gather packs the rows its samples reach; the rows it shares with
    # the previous band are moved, not packed again. With bands of 8 rows and a reach of a few
    # pixels (margins shorter than a band, so that bands share some rows and not all), the result
    # is the one-band result to the bit (the same packed values), and the reference's (the
    # autouse fixture compares each call with the NumPy code).
    from sss_lab.core.techniques.burley import technique as burley_module

    passes, scene, albedo, _ = _scene(96, 64)
    args = dict(
        diffuse=passes["Diffuse Direct"] + passes["Diffuse Indirect"], albedo=albedo, depth=passes["Depth"],
        mask=passes["Material Index"] > 0, camera=scene.camera, d_su=(0.012, 0.005, 0.0025), seed=3,
    )  # fmt: skip
    whole = burley(**args)
    monkeypatch.setattr(burley_module, "_BAND_ROWS", 8)
    packed = []
    original = backend.run_kernel

    pack = backend.kernels(burley_module.__package__).burley_pack

    def spy(kernel, *a):
        if kernel is pack:
            packed.append((a[-4], a[-2].shape[0]))  # first row packed, rows packed
        original(kernel, *a)

    monkeypatch.setattr(backend, "run_kernel", spy)
    banded = burley(**args)
    np.testing.assert_array_equal(banded, whole)
    # Every row of the frame the samples reach is packed once: the bands shared rows.
    assert len(packed) > 2
    firsts = [first for first, _ in packed]
    assert firsts == sorted(firsts)
    assert all(a + n == b for (a, n), (b, _) in zip(packed, packed[1:], strict=False))


def test_sta_mask_spans_read_32_bytes_at_a_time_give_each_rows_first_and_last():
    # The STA kernel finds each row's masked span 32 mask bytes at a time (core.compute.jit.bytes_span):
    # the same (first, last + 1) as one byte at a time, on rows shorter and longer than 32, empty
    # (an empty span, first >= last + 1), full, and with the span's ends on and off the 32-byte steps.
    mod = backend.compiled()  # core.compute.jit
    rng = np.random.default_rng(5)
    rows = [np.zeros(n, bool) for n in (1, 31, 32, 33, 100)] + [np.ones(n, bool) for n in (1, 32, 65)]
    for _ in range(300):
        row = np.zeros(int(rng.integers(1, 200)), bool)
        a, b = sorted(int(v) for v in rng.integers(0, row.size + 1, 2))
        row[a:b] = rng.random(b - a) < 0.7
        rows.append(row)
    for row in rows:
        first = np.flatnonzero(row)
        got = mod.bytes_span(row.view(np.uint8))
        assert got == mod.span(row), row
        if first.size:
            assert got == (int(first[0]), int(first[-1]) + 1), row
        else:
            assert got[0] >= got[1], row


def test_sta_masks_of_every_shape_match_the_reference():
    # Work items of core.techniques.sta._kernels.STA_ROWS rows: rows with no masked pixel (whole rows of zeros),
    # items with none at all, and spans of different widths, against the reference.
    passes, scene, albedo, normal = _scene(70, 53)
    rng = np.random.default_rng(9)
    mask = np.zeros((53, 70), bool)
    for y in range(20, 53):
        a, b = sorted(int(v) for v in rng.integers(0, 71, 2))
        mask[y, a:b] = True
    mask[40:44] = False
    out = sta(
        albedo=albedo, normal=normal, position=passes["Position"], thickness=passes["Thickness"], mask=mask,
        camera=scene.camera, lights=scene.lights, mfp_su=(0.03, 0.01, 0.005), thickness_distance_su=0.1,
    )  # fmt: skip
    assert np.all(out[~mask] == 0) and np.any(out[mask] > 0)


def test_sta_rows_wider_than_a_segment_match_the_reference_to_the_bit():
    # core.techniques.sta._kernels.sta_kernel takes a row's masked span STA_SEGMENT pixels at a time: spans
    # that fill a row, cross the segments' border, start or end beside it, or lie beyond it,
    # against the reference (the same float32 operations in the same order: equal to the bit).
    seg = backend.kernels("sss_lab.core.techniques.sta").STA_SEGMENT
    w = seg + 77
    passes, scene, _, _ = _scene(w, 6)
    rng = np.random.default_rng(12)
    albedo = rng.random((6, w, 3), dtype=np.float32)
    normal = rng.normal(size=(6, w, 3)).astype(np.float32)
    thickness = rng.random((6, w), dtype=np.float32)
    # Points around one in the frame's middle (its edges are background, which no light reaches).
    position = (passes["Position"][3, w // 2] + rng.normal(scale=0.1, size=(6, w, 3))).astype(np.float32)
    mask = np.zeros((6, w), bool)
    mask[0] = True
    mask[1, 5 : seg + 3] = True
    mask[2, seg + 10 : w - 4] = True
    mask[3, seg - 1 : seg + 1] = True
    mask[5, 300:seg] = True
    kw = dict(
        albedo=albedo, normal=normal, position=position, thickness=thickness, mask=mask,
        camera=scene.camera, lights=scene.lights,
    )  # fmt: skip
    medium = dict(
        falloff="medium", mfp_su=(0.03, 0.01, 0.005), thickness_distance_su=0.1, subsurface_method="RANDOM_WALK"
    )
    for falloff in (dict(falloff="map"), medium):
        with backend.use("numpy"):
            reference = sta(**kw, **falloff)
        with backend.use("numba"):
            out = sta(**kw, **falloff)
        np.testing.assert_array_equal(out, reference)
        assert np.all(out[~mask] == 0)
        assert np.any(out[:, :seg][mask[:, :seg]] > 0) and np.any(out[:, seg:][mask[:, seg:]] > 0)


def test_spread_of_the_light_from_behind_matches_the_reference_to_the_bit():
    # core.techniques.combined._spread_kernels.spread_light against core.techniques.combined.technique's NumPy spread
    # (check mode, bound
    # 0): widths
    # from 0 to beyond the last level, a NaN width, a mask with holes, a frame not square.
    from sss_lab.core.techniques.combined.technique import spread_back_light

    rng = np.random.default_rng(4)
    e = rng.random((37, 150, 3)).astype(np.float32)
    mask = rng.random((37, 150)) < 0.8
    sigma = (rng.random((37, 150, 3)) * 40.0).astype(np.float32)
    sigma[3, 4] = (0.0, np.nan, 300.0)
    out = spread_back_light(e, mask, sigma)
    assert np.array_equal(out[~mask], e[~mask])
    assert np.isnan(out[3, 4, 1]) == bool(mask[3, 4])


@pytest.mark.parametrize("kind", ("PERSP", "ORTHO"))
def test_view_cosine_matches_the_reference_to_the_bit(kind):
    # core.optics._kernels.view_cosine against core.optics.energy's NumPy code (check mode, bound 0): a sphere
    # scene's depth with holes in the mask, NaN, infinite, negative and background depths, a
    # lens shift, on the frame and on a window of it (origin and frame size).
    import dataclasses

    from sss_lab.core.optics import energy

    passes, scene, _, _ = _scene(61, 43)
    camera = dataclasses.replace(scene.camera, type=kind, shift_x=0.07, shift_y=-0.03, ortho_scale=4.0)
    depth = passes["Depth"].copy()
    depth[4, 5], depth[6, 30], depth[20, 2], depth[30, 40] = np.nan, np.inf, -1.0, 2e9
    mask = passes["Material Index"] > 0
    mask[10:13, 20:40] = False
    full = energy.view_cosine(depth, mask, camera)
    assert (full < 1.0).any() and (full == 1.0).any()
    window = (slice(3, 40), slice(7, 55))
    part = energy.view_cosine(depth[window], mask[window], camera, origin=(3, 7), frame=mask.shape)
    with backend.use("numpy"):
        reference = energy.view_cosine(depth[window], mask[window], camera, origin=(3, 7), frame=mask.shape)
    np.testing.assert_array_equal(part, reference)
    # A mask of another size than the depth: an error naming both, on each backend.
    for name in ("numba", "numpy"):
        with backend.use(name), pytest.raises(ValueError):
            energy.view_cosine(depth, mask[:, :-1], camera)


@pytest.mark.parametrize("kind", ("PERSP", "ORTHO"))
def test_normal_view_cosine_matches_the_reference_to_the_bit(kind):
    # core.optics._kernels.normal_cosine against core.optics.energy's NumPy code (check mode, bound 0, and the
    # same pixels known): random normals of any length on a turned camera with a lens shift,
    # with NaN, infinite, zero, tiny and huge normals, holes in the mask, on the frame and on a
    # window of it.
    import dataclasses

    from sss_lab.core.optics import energy

    passes, scene, _, _ = _scene(61, 43)
    a, b = math.radians(30.0), math.radians(-50.0)
    world = np.eye(4)
    world[:3, :3] = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]]) @ np.array(
        [[math.cos(b), -math.sin(b), 0], [math.sin(b), math.cos(b), 0], [0, 0, 1]]
    )
    world[:3, 3] = (0.5, -2.0, 1.0)
    camera = dataclasses.replace(
        scene.camera, type=kind, shift_x=0.07, shift_y=-0.03, ortho_scale=4.0, matrix_world=tuple(world.ravel())
    )
    rng = np.random.default_rng(11)
    normal = (rng.normal(size=(43, 61, 3)) * rng.uniform(0.01, 3.0, (43, 61, 1))).astype(np.float32)
    normal[4, 5], normal[6, 30, 1], normal[20, 2] = np.nan, np.inf, 0.0
    normal[30, 40], normal[31, 40] = (1e-30, -2e-30, 3e-30), (3e38, -1e38, 2e38)
    mask = np.ones((43, 61), bool)
    mask[10:13, 20:40] = False
    cos, known = energy.normal_view_cosine(normal, mask, camera)
    assert known.sum() == mask.sum() - 3 and np.all(cos[~known] == 1.0)
    assert (cos < 0.5).any() and (cos > 0.9).any()
    assert known[30, 40] and known[31, 40]  # tiny and huge normals are read like unit ones
    window = (slice(3, 40), slice(7, 55))
    part, part_known = energy.normal_view_cosine(normal[window], mask[window], camera, origin=(3, 7), frame=mask.shape)
    np.testing.assert_array_equal(part, cos[window])
    np.testing.assert_array_equal(part_known, known[window])


def test_energy_table_reads_and_curvature_match_the_reference_to_the_bit():
    # core.optics._kernels.table_lerp, curvature_pixels and smooth_curvature against core.optics.energy's NumPy
    # code (check mode, bound 0), with values beyond the tables, NaN and infinite inputs.
    from sss_lab.core.optics import energy

    rng = np.random.default_rng(6)
    a = rng.random((500, 3)) * 1.2 - 0.1
    a[:3] = (np.nan, np.inf, -np.inf)
    k = rng.random((500, 3)) * 3.0 - 0.5
    k[3:6] = (np.nan, np.inf, -np.inf)
    mu = rng.random(500) * 1.2 - 0.1
    mu[7] = np.nan
    energy.entry_gain("RANDOM_WALK", a, mu)
    energy.convex_gain("RANDOM_WALK_SKIN", a, k)
    energy.slab_factors("RANDOM_WALK", a, np.abs(k) * 200.0)
    passes, scene, _, normal = _scene(61, 43)
    position = passes["Position"].copy()
    position[5, 7] = np.nan
    normal = normal.copy()
    normal[9, 9] = 0.1
    for radius in (1, 4):
        energy.surface_curvature(normal, position, passes["Material Index"] > 0, radius_px=radius)
    # Several radii in one call (the energy stage's per channel reaches), one wider than the frame.
    parts = energy._curvature_per_pixel(normal, position, passes["Material Index"] > 0)
    maps = energy._smoothed_curvatures(parts, [3, 1, 3, 70])
    assert sorted(maps) == [1, 3, 70] and maps[70][1] is not None and maps[3][1] is None


def test_vector_length_is_numpys_norm_to_the_bit():
    # arrays.vector_length stands in for np.linalg.norm(v, axis=-1, keepdims=True) in the view
    # vectors and the view cosine: the same bits, NaN, infinities, zeros and overflow included.
    from sss_lab.core.base import arrays

    rng = np.random.default_rng(3)
    for shape in ((50, 37, 3), (7, 1, 3), (64, 3)):
        scale = rng.choice(np.array([1e-20, 1e-3, 1.0, 1e3, 1e19], np.float32), size=shape)
        v = (rng.standard_normal(shape) * scale).astype(np.float32)
        v.reshape(-1, 3)[0] = (np.nan, 1.0, 2.0)
        v.reshape(-1, 3)[1] = (np.inf, 0.0, 0.0)
        v.reshape(-1, 3)[2] = 0.0
        with np.errstate(over="ignore", invalid="ignore"):
            expected = np.linalg.norm(v, axis=-1, keepdims=True)
            got = arrays.vector_length(v)
        assert got.dtype == expected.dtype == np.float32
        assert got.shape == expected.shape
        assert got.tobytes() == expected.tobytes()


def test_one_thread_holds_one_thread_and_restores_the_count():
    import numba

    before = numba.get_num_threads()
    with backend.use("numba"):
        with backend.one_thread():
            assert numba.get_num_threads() == 1
        assert numba.get_num_threads() == before
        with pytest.raises(RuntimeError), backend.one_thread():
            raise RuntimeError("the count is restored on the way out of an error too")
        assert numba.get_num_threads() == before
