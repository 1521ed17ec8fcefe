"""The three techniques (core/techniques/sta/technique.py, core/techniques/ssss/technique.py,
core/techniques/burley/technique.py): the slide deck's worked
example, separability, per-channel spread, energy, and the extremes, each with its expected result."""

import math

import numpy as np
import pytest

from sss_lab.core.optics import kernels
from sss_lab.core.scene.scene import Camera, Light
from sss_lab.core.techniques.burley.technique import burley
from sss_lab.core.techniques.ssss.technique import filter_1d, ssss
from sss_lab.core.techniques.sta.technique import sta


# Orthographic camera with exactly 1 pixel per scene unit, so kernels in scene units are in pixels.
def _cam(w, h, px_per_unit=1.0):
    return Camera(type="ORTHO", width_px=w, height_px=h, ortho_scale=max(w, h) / px_per_unit)


SKIN_D = (0.03, 0.012, 0.006)  # scene units; at 100 px/unit: 3 / 1.2 / 0.6 px
GRID = np.array([[12, 18, 15], [20, 30, 22], [14, 19, 16]], np.float32)


def _flat(h, w, value=1.0, depth=5.0):
    e = np.full((h, w, 3), value, np.float32)
    a = np.ones((h, w, 3), np.float32)
    z = np.full((h, w), depth, np.float32)
    return e, a, z, np.ones((h, w), bool)


def _run(fn, e, a, z, m, cam, **kw):
    if fn is ssss:
        kw.setdefault("d_su", SKIN_D)
    else:
        kw.setdefault("d_su", SKIN_D)
    return fn(diffuse=e, albedo=a, depth=z, mask=m, camera=cam, **kw)


def test_slide_deck_worked_example():
    img = np.repeat(GRID[..., None], 3, axis=2)
    k2 = np.array([[1, 2, 1], [2, 4, 2], [1, 2, 1]]) / 16
    assert float((k2 * GRID).sum()) == 20.9375
    w1 = np.array([1, 2, 1]) / 4
    horizontal = filter_1d(img, offsets_px=[-1, 0, 1], weights=w1, axis=1)
    assert horizontal[:, 1, 0].tolist() == [15.75, 25.5, 17.0]
    both = filter_1d(horizontal, offsets_px=[-1, 0, 1], weights=w1, axis=0)
    assert both[1, 1, 0] == 20.9375
    # The full technique with the same kernel (1 px per scene unit) gives the same number.
    kernel = kernels.SeparableKernel(np.array([-1.0, 0.0, 1.0]), np.repeat(w1[:, None], 3, axis=1))
    out = ssss(
        diffuse=img,
        albedo=np.ones_like(img),
        depth=np.full((3, 3), 5.0, np.float32),
        mask=np.ones((3, 3), bool),
        camera=_cam(3, 3),
        kernel=kernel,
    )
    assert out[1, 1, 0] == pytest.approx(20.9375, abs=1e-5)


def test_separable_passes_equal_the_2d_convolution_of_a_separable_kernel():
    rng = np.random.default_rng(3)
    img = rng.random((40, 50, 3)).astype(np.float32)
    offsets = np.array([-3.0, -1.0, 0.0, 1.0, 3.0])
    w = np.array([[0.1, 0.2, 0.4, 0.2, 0.1], [0.05, 0.25, 0.4, 0.25, 0.05], [0.0, 0.1, 0.8, 0.1, 0.0]]).T
    sep = filter_1d(filter_1d(img, offsets_px=offsets, weights=w, axis=1), offsets_px=offsets, weights=w, axis=0)
    for c in range(3):
        k2 = np.outer(w[:, c], w[:, c])
        direct = np.zeros((34, 44))
        for i, oy in enumerate(offsets.astype(int)):
            for j, ox in enumerate(offsets.astype(int)):
                direct += k2[i, j] * img[3 + oy : 37 + oy, 3 + ox : 47 + ox, c]
        # float32 accumulation of 25 terms: about 1e-6 relative.
        assert np.allclose(sep[3:37, 3:47, c], direct, rtol=1e-5, atol=1e-6)


def _second_moment(img, cy, cx):
    y, x = np.mgrid[: img.shape[0], : img.shape[1]]
    r2 = (y - cy) ** 2 + (x - cx) ** 2
    return (img * r2[..., None]).sum(axis=(0, 1)) / img.sum(axis=(0, 1))


def _three_pixels_lit_from_behind():
    """A row of three pixels facing an orthographic camera, a sun of irradiance pi straight behind
    them (shining towards the camera): (camera, normal, position, light)."""
    cam = Camera(type="ORTHO", width_px=3, height_px=1)
    n = np.zeros((1, 3, 3), np.float32)
    n[..., 2] = 1.0
    p = np.zeros((1, 3, 3), np.float32)
    p[..., 2] = -5.0
    back = Light(type="SUN", energy=math.pi, matrix_world=(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1))
    return cam, n, p, back


def test_sta_medium_falloff_filters_light_through_the_materials_medium():
    # A jade-like walk (green Base Color, red going furthest) seen straight on, a sun straight
    # behind: translucency 1, 0.75 and 0.19 against the bake distance D = 0.02 are slabs of 0,
    # 1 and 1.8 cm (x = D sqrt(1 - t), the bake's slab law).
    from sss_lab.core.optics.medium import Medium, slab_transmittance_rgb

    cam, n, p, back = _three_pixels_lit_from_behind()
    base = (0.3, 0.8, 0.4)
    mfp = (0.004, 0.002, 0.001)
    # Diffuse Color = Base Color x 0.9 (a specular layer's share): the exit weight is 0.9 everywhere.
    albedo = np.tile(np.asarray(base, np.float32) * np.float32(0.9), (1, 3, 1))
    tau = np.array([[1.0, 0.75, 0.19]], np.float32)
    kw = dict(
        albedo=albedo, normal=n, position=p, thickness=tau, mask=np.ones((1, 3), bool), camera=cam,
        lights=[back], distortion=0.0, mfp_su=mfp, thickness_distance_su=0.02,
        subsurface_method="RANDOM_WALK", base_color=base,
    )  # fmt: skip
    out = sta(**kw)
    # Lobe 1 and E / pi = 1: what is left is the exit weight times the walk's slab transmittance,
    # which colours the light (the walk's medium), not the albedo, which would colour it twice;
    # tabulated (core.techniques.sta.technique.medium_table): within 0.01 of the thin part's light.
    x = 0.02 * np.sqrt(1.0 - tau[0].astype(np.float64))
    want = 0.9 * slab_transmittance_rgb(x, mfp, Medium("RANDOM_WALK", base), view_cos=np.ones(3))
    assert np.allclose(out[0], want, rtol=0, atol=0.9 * 0.01)
    assert np.allclose(out[0], want, rtol=0.01, atol=1e-6)  # here, where nothing is cut, within 1 %
    # A part of no thickness passes all of it; thicker parts pass less, and the light turns a more
    # saturated green with the thickness (the jade: random walk's green, not the pale albedo).
    assert np.allclose(out[0, 0], 0.9, rtol=0.02)
    assert np.all(out[0, 1] < out[0, 0]) and np.all(out[0, 2] < out[0, 1]) and np.all(out[0, 2] > 0)
    green = out[0, :, 1] / out[0, :, [0, 2]].max(axis=0)
    assert green[2] > green[1] > green[0]
    # The paper's map passes 0.19 of the albedo's pale colour there, whatever the material's lengths.
    paper = sta(**{**kw, "falloff": "map"})
    assert np.allclose(paper[0, 2], 0.19 * albedo[0, 2], rtol=1e-5)
    # Christensen-Burley keeps the closure weight (Diffuse Color) and the disk probes' far side.
    disk = sta(**{**kw, "subsurface_method": "BURLEY"})
    want = albedo[0] * slab_transmittance_rgb(x, mfp, Medium("BURLEY", base))
    assert np.allclose(disk[0], want, rtol=0, atol=0.01)
    # The map read as a thickness needs the material's lengths and the bake's distance.
    with pytest.raises(ValueError, match="falloff 'medium' .* needs mfp_su .* thickness_distance_su"):
        sta(**{**kw, "thickness_distance_su": 0.0})
    with pytest.raises(ValueError, match="falloff 'medium'"):
        sta(**{**kw, "mfp_su": None})


@pytest.mark.parametrize("method", ("RANDOM_WALK", "RANDOM_WALK_SKIN", "RANDOM_WALK_LEGACY", "BURLEY", None))
@pytest.mark.parametrize("distance_mfp", (1.0, 5.0, 20.0, 60.0))
def test_sta_medium_table_follows_the_transmittance_it_tabulates(method, distance_mfp):
    # The "medium" falloff reads a table over thickness and view cosine (core.techniques.sta.technique.medium_table):
    # within 0.01 of the light through no thickness (1) of the model itself, for pale, skin-like
    # and saturated materials at bake distances of 1 to 60 of the longest mean free path.
    from sss_lab.core.optics.medium import Medium, slab_transmittance_rgb
    from sss_lab.core.techniques.sta import technique as sta_module

    rng = np.random.default_rng(3)
    mfp = (0.004, 0.002, 0.001)
    distance = 0.004 * distance_mfp
    for base in ((0.35, 0.62, 0.42), (0.44, 0.23, 0.13), (0.9, 0.85, 0.8)):
        medium = None if method is None else Medium(method, base)
        table = sta_module.medium_table(mfp, distance, medium)
        t = rng.random(2000).astype(np.float32)
        mu = rng.random(2000).astype(np.float32)
        got = sta_module._lookup(table, t, mu)
        x = distance * np.sqrt(1.0 - t.astype(np.float64))
        walks = medium is not None and medium.walks
        want = slab_transmittance_rgb(x, mfp, medium, view_cos=mu if walks else None)
        assert np.abs(got - want).max() < 0.01, (base, float(np.abs(got - want).max()))


@pytest.mark.parametrize("fn", (ssss, burley))
def test_red_spreads_wider_than_blue_and_impulse_energy_is_kept(fn):
    e, a, z, m = _flat(61, 61, 0.0)
    e[30, 30] = 1.0
    # 50 px per unit: the red kernel reaches 16 d = 24 px, inside the image.
    out = _run(fn, e, a, z, m, _cam(61, 61, 50.0))
    spread = _second_moment(out, 30, 30)
    assert spread[0] > spread[1] > spread[2]
    if fn is ssss:  # a normalized kernel, applied away from the borders, keeps the impulse exactly
        assert np.allclose(out.sum(axis=(0, 1)), 1.0, atol=1e-5)


@pytest.mark.parametrize("fn", (ssss, burley))
def test_energy_on_a_flat_fully_masked_plane(fn):
    # Light falls on a pattern well inside the image: nothing reaches the borders (at 30 px per
    # unit the red kernel ends at 16 d = 14.4 px; the pattern is 24 px from them).
    rng = np.random.default_rng(7)
    e, a, z, m = _flat(96, 96, 0.0)
    e[24:72, 24:72] = rng.random((48, 48, 3)).astype(np.float32) + np.float32(0.5)
    e[40:56, 40:56] = 3.0  # a bright square: a sharp edge to spread
    out = _run(fn, e, a, z, m, _cam(96, 96, 30.0))
    ratio = out.sum(axis=(0, 1)) / e.sum(axis=(0, 1))
    assert np.all(np.abs(ratio - 1) < 0.005), ratio  # the 0.5 %


def test_sta_adds_light_from_behind_and_none_from_the_front():
    h, w = 4, 5
    cam = Camera(type="ORTHO", width_px=w, height_px=h)  # looks down -Z from the origin
    normal = np.zeros((h, w, 3), np.float32)
    normal[..., 2] = 1.0  # facing the camera
    pos = np.zeros((h, w, 3), np.float32)
    pos[..., 2] = -5.0
    albedo = np.full((h, w, 3), 0.5, np.float32)
    thick = np.full((h, w), 1.0, np.float32)
    mask = np.ones((h, w), bool)
    # A sun shining towards the camera (+Z) lights the back: L = -Z, V = +Z, L_T = L + 0.1 N.
    back = Light(type="SUN", energy=math.pi, matrix_world=(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1))
    # The paper's arithmetic; the "medium" falloff has its own test.
    paper = dict(albedo=albedo, normal=normal, position=pos, thickness=thick, mask=mask, camera=cam, falloff="map")
    out = sta(lights=[back], **paper)
    # V . -L_T = 1 (normalized), so T_dir = 1: added = 0.5 x (pi / pi) x 1 x 1.
    assert np.allclose(out, 0.5, atol=1e-6)
    front = Light(type="SUN", energy=math.pi)  # shines down -Z, from the camera's side
    out = sta(lights=[front], **paper)
    assert np.all(out == 0)
    # Thickness 0 adds nothing; ambient adds a_T even where the lobe is 0; the mask limits it.
    kw = dict(albedo=albedo, normal=normal, position=pos, mask=mask, camera=cam, falloff="map")
    assert np.all(sta(thickness=np.zeros((h, w)), lights=[back], **kw) == 0)
    amb = sta(thickness=thick, lights=[front], ambient=0.2, **kw)
    assert np.allclose(amb, 0.5 * 0.2, atol=1e-6)
    half = mask.copy()
    half[:, :2] = False
    assert np.all(sta(thickness=thick, lights=[back], **{**kw, "mask": half})[:, :2] == 0)
    # The thickness convention reads 1 - t.
    assert np.all(sta(thickness=thick, lights=[back], thickness_convention="thickness", **kw) == 0)


def test_sta_extremes():
    cam = Camera(type="ORTHO", width_px=1, height_px=1)
    n = np.array([[[0, 0, 1]]], np.float32)
    p = np.array([[[0, 0, -5]]], np.float32)
    a = np.ones((1, 1, 3), np.float32)
    t = np.ones((1, 1), np.float32)
    m = np.ones((1, 1), bool)
    back = Light(type="SUN", energy=math.pi, matrix_world=(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1))
    kw = dict(albedo=a, normal=n, position=p, thickness=t, mask=m, camera=cam, lights=[back], falloff="map")
    # d_T = 1 makes L + d_T N = -Z + Z = 0: undefined direction, no light (not NaN).
    out = sta(distortion=1.0, **kw)
    assert np.all(out == 0) and np.all(np.isfinite(out))
    # Grazing light (along the surface, from the side): V . -L_T = -0.1 / |L_T| < 0 with d_T = 0.1 -> nothing.
    side = Light(type="SUN", energy=1.0, matrix_world=(0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 1))
    assert np.all(sta(**{**kw, "lights": [side]}) == 0)
    # p_T = 0: s_T wherever the lobe is positive; p_T = 128 stays finite and equals 1 here (V . -L_T = 1).
    assert np.allclose(sta(power=0.0, scale=2.0, **kw), 2.0)
    assert np.allclose(sta(power=128.0, **kw), 1.0)
    with pytest.raises(ValueError, match="power: expected a finite number >= 0"):
        sta(power=-1, **kw)
    with pytest.raises(ValueError, match="thickness_convention"):
        sta(thickness_convention="bright", **kw)


def test_sta_point_and_spot_attenuation():
    cam = Camera(type="ORTHO", width_px=1, height_px=1)
    kw = dict(
        albedo=np.ones((1, 1, 3), np.float32),
        normal=np.array([[[0, 0, 1]]], np.float32),
        position=np.array([[[0, 0, -5]]], np.float32),
        thickness=np.ones((1, 1)),
        mask=np.ones((1, 1), bool),
        camera=cam,
        distortion=0.0,
        falloff="map",
    )
    # A point light 2 units behind: E = P / (4 pi r^2), lobe 1.
    point = Light(type="POINT", energy=100.0, matrix_world=(1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, -7, 0, 0, 0, 1))
    expected = 100.0 / (4 * math.pi * 4) / math.pi
    assert sta(lights=[point], **kw)[0, 0, 0] == pytest.approx(expected, rel=1e-5)
    # A spot at the same place pointing away (+Z is its -Z axis flipped) gives nothing; towards: as the point.
    toward = Light(type="SPOT", energy=100.0, matrix_world=(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, -7, 0, 0, 0, 1))
    away = Light(type="SPOT", energy=100.0, matrix_world=(1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, -7, 0, 0, 0, 1))
    assert sta(lights=[toward], **kw)[0, 0, 0] == pytest.approx(expected, rel=1e-5)
    assert sta(lights=[away], **kw)[0, 0, 0] == 0


@pytest.mark.parametrize("fn", (ssss, burley))
@pytest.mark.parametrize("d", ((0.0, 0.0, 0.0), (1e-9, 1e-9, 1e-9)))
def test_zero_and_tiny_radius_give_the_input(fn, d):
    rng = np.random.default_rng(1)
    e = rng.random((9, 11, 3)).astype(np.float32)
    a = rng.random((9, 11, 3)).astype(np.float32)
    z = np.full((9, 11), 3.0, np.float32)
    out = _run(fn, e, a, z, np.ones((9, 11), bool), _cam(11, 9, 100.0), d_su=d)
    assert np.array_equal(out, a * e)


@pytest.mark.parametrize("fn", (ssss, burley))
def test_radius_far_larger_than_the_image(fn):
    # d = 100 px on a 24 x 20 image: every tap lands off the image or on the same plane, the
    # result is a finite average of the image (between its min and max).
    rng = np.random.default_rng(2)
    e = rng.random((20, 24, 3)).astype(np.float32) + 0.1
    a = np.ones_like(e)
    out = _run(fn, e, a, np.full((20, 24), 2.0, np.float32), np.ones((20, 24), bool), _cam(24, 20), d_su=(100,) * 3)
    assert np.all(np.isfinite(out))
    assert out.min() >= e.min() - 1e-5 and out.max() <= e.max() + 1e-5


@pytest.mark.parametrize("fn", (ssss, burley))
def test_nan_inf_huge_values_background_and_masks(fn):
    h, w = 32, 32
    e, a, z, m = _flat(h, w, 1.0)
    e[10, 10] = np.nan
    e[20, 20] = np.inf
    e[5, 25] = 1e6  # above the half-float limit
    z[:, 28:] = 1e10  # background
    cam = _cam(w, h, 100.0)
    out = _run(fn, e, a, z, m, cam)
    # NaN and Inf stay where they are and do not spread over the kernel footprint.
    assert np.isnan(out[10, 10]).all() and np.isinf(out[20, 20]).all()
    bad = ~np.isfinite(out).all(axis=2)
    assert bad.sum() == 2
    # The huge value spreads as a float32 (no overflow to inf) and the background is untouched.
    assert out[5, 26, 0] > 1.0 and np.isfinite(out).sum() == out.size - 6
    assert np.array_equal(out[:, 28:], (a * e)[:, 28:])
    # Light does not leak from the masked-out region: a bright unmasked block gives nothing.
    e2, a2, z2, m2 = _flat(h, w, 1.0)
    e2[:, :8] = 100.0
    m2[:, :8] = False
    out2 = _run(fn, e2, a2, z2, m2, cam)
    assert np.allclose(out2[:, 8:], 1.0, atol=1e-6)
    # Empty mask: the input, unchanged.
    assert np.array_equal(_run(fn, e, a, z, np.zeros((h, w), bool), cam), a * e, equal_nan=True)


@pytest.mark.parametrize("fn", (ssss, burley))
@pytest.mark.parametrize("shape", ((1, 1), (1, 17), (17, 1)))
def test_one_pixel_and_one_row_images(fn, shape):
    e, a, z, m = _flat(*shape, 2.0)
    out = _run(fn, e, a, z, m, _cam(shape[1], shape[0], 100.0))
    assert out.shape == (*shape, 3) and np.allclose(out, 2.0, atol=1e-6)


@pytest.mark.parametrize("fn", (ssss, burley))
@pytest.mark.parametrize("dtype", (np.float16, np.float64))
def test_half_and_double_inputs_give_float32(fn, dtype):
    e, a, z, m = _flat(16, 16, 1.0)
    e[8, 8] = 60000.0
    ref = _run(fn, e, a, z, m, _cam(16, 16, 100.0))
    out = _run(fn, e.astype(dtype), a.astype(dtype), z.astype(dtype), m, _cam(16, 16, 100.0))
    assert out.dtype == np.float32
    assert np.allclose(out, ref, rtol=1e-3)  # half floats hold 11 significant bits


def test_follow_surface_and_object_ids_stop_light_at_depth_jumps():
    h, w = 20, 40
    e, a, z, m = _flat(h, w, 1.0)
    e[:, 20:] = 10.0
    z[:, 20:] = 50.0  # far behind: a silhouette edge
    cam = _cam(w, h, 100.0)
    ids = np.ones((h, w), np.float32)
    ids[:, 20:] = 2
    near = burley(diffuse=e, albedo=a, depth=z, mask=m, camera=cam, d_su=SKIN_D, object_id=ids)
    assert np.allclose(near[:, :20], 1.0)
    no_ids = burley(diffuse=e, albedo=a, depth=z, mask=m, camera=cam, d_su=SKIN_D)
    assert np.allclose(no_ids[:, :20], 1.0, atol=1e-6)  # the 3-D distance (45 units) kills the weight
    fs = ssss(diffuse=e, albedo=a, depth=z, mask=m, camera=cam, d_su=SKIN_D)
    assert np.allclose(fs[:, :20], 1.0, atol=1e-6)
    leak = ssss(diffuse=e, albedo=a, depth=z, mask=m, camera=cam, d_su=SKIN_D, follow_surface=False)
    assert leak[:, 19].mean() > 1.1  # without follow-surface light crosses the edge


def test_random_rotation_is_seeded_and_keeps_the_mean():
    rng = np.random.default_rng(0)
    e, a, z, m = _flat(48, 48, 1.0)
    e[:, :24] = rng.random((48, 24, 3)).astype(np.float32)
    cam = _cam(48, 48, 100.0)
    kw = dict(diffuse=e, albedo=a, depth=z, mask=m, camera=cam, d_su=SKIN_D)
    r1 = burley(random_rotation=True, seed=4, **kw)
    assert np.array_equal(r1, burley(random_rotation=True, seed=4, **kw))
    assert not np.array_equal(r1, burley(random_rotation=True, seed=5, **kw))
    assert not np.array_equal(r1, burley(**kw))


def test_perspective_footprint_shrinks_with_depth():
    cam = Camera(type="PERSP", width_px=64, height_px=64)
    e, a, z, m = _flat(64, 64, 0.0)
    e[32, 32] = 1.0
    spreads = []
    for depth in (2.0, 8.0):
        z[:] = depth
        out = burley(diffuse=e, albedo=a, depth=z, mask=m, camera=cam, d_su=(0.02, 0.02, 0.02))
        spreads.append(_second_moment(out, 32, 32)[0])
    assert spreads[0] > 4 * spreads[1]


@pytest.mark.parametrize("fn", (ssss, burley))
def test_bad_input_names_the_value(fn):
    e, a, z, m = _flat(8, 8)
    cam = _cam(8, 8)
    with pytest.raises(ValueError, match=r"albedo: shape \(8, 7\) does not match"):
        _run(fn, e, a[:, :7], z, m, cam)
    with pytest.raises(ValueError, match=r"diffuse: expected shape \(H, W, 3\)"):
        _run(fn, e[..., 0], a, z, m, cam)
    with pytest.raises(ValueError, match="d_su: expected three finite lengths >= 0"):
        _run(fn, e, a, z, m, cam, d_su=(-1, 1, 1))
    with pytest.raises(ValueError, match="mask: expected shape"):
        _run(fn, e, a, z, m[:4], cam)
    with pytest.raises(ValueError, match="albedo_mode"):
        _run(fn, e, a, z, m, cam, albedo_mode="pre")
    with pytest.raises(ValueError, match="camera: expected"):
        _run(fn, e, a, z, m, "cam")


def test_sta_burley_falloff_filters_light_by_thickness_per_channel():
    cam, n, p, back = _three_pixels_lit_from_behind()
    # Translucency 1 (no thickness), 0.75 and 0 (thicker than the bake distance D = 0.04).
    tau = np.array([[1.0, 0.75, 0.0]], np.float32)
    d = (0.01, 0.004, 0.002)
    kw = dict(
        albedo=np.ones((1, 3, 3), np.float32),
        normal=n,
        position=p,
        thickness=tau,
        mask=np.ones((1, 3), bool),
        camera=cam,
        lights=[back],
        distortion=0.0,
    )
    out = sta(falloff="burley", d_su=d, thickness_distance_su=0.04, **kw)
    # A part of zero thickness passes everything: the same as the paper's map there.
    assert np.allclose(out[0, 0], 1.0, atol=1e-6)
    assert np.allclose(out[0, 0], sta(falloff="map", **kw)[0, 0], atol=1e-6)
    # tau = 0.75 is a slab of 0.04 x sqrt(0.25) = 0.02: T_c = (e^{-x/d} + 3 e^{-x/3d}) / 4.
    x = 0.02
    expected = [0.25 * (math.exp(-x / dc) + 3 * math.exp(-x / (3 * dc))) for dc in d]
    assert np.allclose(out[0, 1], expected, rtol=1e-5)
    # Red, which scatters furthest, gets through best; nothing is negative or above the thin case.
    assert out[0, 2, 0] > out[0, 2, 1] > out[0, 2, 2] >= 0
    with pytest.raises(ValueError, match="thickness_distance_su: expected a finite number > 0"):
        sta(falloff="burley", d_su=d, **kw)
    with pytest.raises(ValueError, match="falloff: 'hdrp' is not one of medium, map, burley"):
        sta(falloff="hdrp", **kw)
