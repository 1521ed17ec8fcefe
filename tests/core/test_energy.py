"""The entry energy of Cycles' subsurface methods (core/optics/energy.py): the table's lookup, the view
angle from the Depth pass, and the techniques that apply it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sss_lab.core.optics import energy
from sss_lab.core.scene.scene import Camera
from sss_lab.core.techniques.burley.technique import burley
from sss_lab.core.techniques.ssss.technique import ssss


def _mu(view_deg):
    return math.cos(math.radians(view_deg))


@pytest.mark.parametrize("method", sorted(energy.SEMI_INFINITE))
def test_the_table_is_returned_at_its_nodes(method):
    table = energy.SEMI_INFINITE[method]
    assert len(table) == len(energy.VIEW_DEG)
    for view, row in zip(energy.VIEW_DEG, table, strict=True):
        assert len(row) == len(energy.ALBEDO)
        for k in range(0, len(energy.ALBEDO) - 2, 3):
            a = np.array([[energy.ALBEDO[k], energy.ALBEDO[k + 1], energy.ALBEDO[k + 2]]])
            got = energy.entry_gain(method, a, np.array([_mu(view)]))
            np.testing.assert_allclose(got[0], row[k : k + 3], rtol=1e-5)


def test_between_nodes_it_interpolates_and_outside_it_clamps():
    method = "RANDOM_WALK"
    t = np.array(energy.SEMI_INFINITE[method])
    # Halfway between the first two albedos, at normal view: the mean of the two entries.
    a = np.array([[0.5 * (energy.ALBEDO[0] + energy.ALBEDO[1])] * 3])
    got = energy.entry_gain(method, a, np.array([1.0]))
    np.testing.assert_allclose(got[0], 0.5 * (t[0, 0] + t[0, 1]), rtol=1e-5)
    # Beyond the table: albedo 0 and 1 read its ends, a view past 85 degrees its last row.
    got = energy.entry_gain(method, np.array([[0.0, 1.0, 0.5]]), np.array([0.0]))
    np.testing.assert_allclose(got[0, :2], [t[-1, 0], t[-1, -1]], rtol=1e-5)


def test_christensen_burley_and_unknown_methods_keep_the_lambert_energy():
    a = np.full((4, 3), 0.5, np.float32)
    mu = np.linspace(0.1, 1.0, 4)
    assert np.array_equal(energy.entry_gain("BURLEY", a, mu), np.ones((4, 3), np.float32))


def _plane_depth(camera: Camera, tilt_deg: float, h: int, w: int, z0: float = 2.0) -> np.ndarray:
    """Planar depth of a plane through (0, 0, -z0) in camera space, tilted about the camera's x
    axis by ``tilt_deg`` (normal (0, sin, cos))."""
    t = math.radians(tilt_deg)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    if camera.type == "ORTHO":
        s = 1.0 / camera.ortho_px_per_unit
        y = (h / 2 - ys - 0.5) * s
        # n . (p - p0) = 0 with p = (x, y, -z): sin(t) y - cos(t) (z - z0) = 0
        return (z0 + math.tan(t) * y).astype(np.float32)
    f = camera.focal_px
    v = (h / 2 - ys - 0.5) / f
    # y = v z: sin(t) v z - cos(t) z + cos(t) z0 = 0
    return (math.cos(t) * z0 / (math.cos(t) - math.sin(t) * v)).astype(np.float32)


def _plane_cosine(camera: Camera, tilt_deg: float, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the normal in camera space, the exact view cosine per pixel) of ``_plane_depth``'s plane
    tilted by ``tilt_deg``, whose depth is ``z``: |n . v| with v the unit vector from each pixel's
    point towards the camera (the axis under an orthographic camera)."""
    h, w = z.shape
    n = np.array([0.0, math.sin(math.radians(tilt_deg)), math.cos(math.radians(tilt_deg))])
    if camera.type == "ORTHO":
        return n, np.full((h, w), n[2])
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    f = camera.focal_px
    p = np.stack([(xs + 0.5 - w / 2) / f * z, (h / 2 - ys - 0.5) / f * z, -z], -1)
    v = -p / np.linalg.norm(p, axis=-1, keepdims=True)
    return n, np.abs(v @ n)


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
@pytest.mark.parametrize("tilt", [0.0, 30.0, 60.0])
def test_view_cosine_of_a_tilted_plane(kind, tilt):
    h = w = 48
    camera = Camera(type=kind, width_px=w, height_px=h, lens_mm=50.0, ortho_scale=1.0)
    z = _plane_depth(camera, tilt, h, w)
    mask = np.ones((h, w), bool)
    mu = energy.view_cosine(z, mask, camera)
    _, expected = _plane_cosine(camera, tilt, z)
    # A plane's differences span it exactly: only float32 depth rounding is left.
    np.testing.assert_allclose(mu, expected, atol=2e-3)


def test_view_cosine_at_a_silhouette_uses_the_surface_side():
    h = w = 32
    camera = Camera(type="ORTHO", width_px=w, height_px=h, ortho_scale=1.0)
    z = _plane_depth(camera, 45.0, h, w)
    mask = np.zeros((h, w), bool)
    mask[:, :16] = True
    z[:, 16:] = 1e10  # background beside the plane
    mu = energy.view_cosine(z, mask, camera)
    np.testing.assert_allclose(mu[:, :16], math.cos(math.radians(45.0)), atol=2e-3)
    assert np.all(mu[:, 16:] == 1.0)


def _turned_camera(kind, h, w):
    """A camera turned 25 degrees about x and 40 about its view axis, at (0.3, -0.2, 0.5): its
    world-space axes differ from camera space in every component."""
    a, b = math.radians(25.0), math.radians(40.0)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    rz = np.array([[math.cos(b), -math.sin(b), 0], [math.sin(b), math.cos(b), 0], [0, 0, 1]])
    world = np.eye(4)
    world[:3, :3] = rx @ rz
    world[:3, 3] = (0.3, -0.2, 0.5)
    matrix = tuple(world.ravel())
    camera = Camera(type=kind, width_px=w, height_px=h, lens_mm=50.0, ortho_scale=1.0, matrix_world=matrix)
    return camera, world[:3, :3]


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
@pytest.mark.parametrize("tilt", [0.0, 30.0, 60.0])
def test_the_normal_passs_view_cosine_is_the_planes(kind, tilt):
    # The plane of test_view_cosine_of_a_tilted_plane, its normal given in world space as the
    # Normal pass holds it, seen by a camera turned in the world: the same cosine as the exact
    # one of the plane's depth, without the depth's rounding.
    h = w = 48
    camera, rotation = _turned_camera(kind, h, w)
    z = _plane_depth(camera, tilt, h, w).astype(np.float64)
    n_camera, expected = _plane_cosine(camera, tilt, z)
    normal = np.broadcast_to((rotation @ n_camera).astype(np.float32), (h, w, 3)).copy()
    mask = np.ones((h, w), bool)
    mu, known = energy.normal_view_cosine(normal, mask, camera)
    assert known.all()
    np.testing.assert_allclose(mu, expected, atol=1e-6)  # float32 products of unit vectors


def test_the_normal_passs_cosine_divides_the_length_and_falls_back_to_the_depth():
    h = w = 32
    camera = Camera(type="ORTHO", width_px=w, height_px=h, ortho_scale=1.0)
    z = _plane_depth(camera, 45.0, h, w)
    s = math.sqrt(0.5)
    normal = np.broadcast_to(np.float32([0.0, s, s]), (h, w, 3)).copy()
    normal[:, :8] *= 0.3  # a silhouette's pixel: the object's normal, shortened by the pixel filter
    normal[:4, 8:] = np.nan  # no normal
    normal[4:8, 8:] = 0.0
    normal[8:12, 8:, 2] = np.inf
    mask = np.ones((h, w), bool)
    mask[:, -2:] = False
    mu, known = energy.normal_view_cosine(normal, mask, camera)
    np.testing.assert_allclose(mu[12:, :-2], s, atol=1e-6)
    assert known[12:, :-2].all() and not known[:12, 8:].any() and not known[:, -2:].any()
    assert np.all(mu[~known] == 1.0)
    # Where the normal is unknown the Depth pass's cosine stands in; the frame's window is read.
    box = (slice(0, h), slice(0, w - 2))
    got = energy.entry_view_cosine(z, normal, mask, camera, box)
    depth_mu = energy.view_cosine(z[box], mask[box], camera)
    np.testing.assert_array_equal(got[:12, 8:], depth_mu[:12, 8:])
    np.testing.assert_allclose(got[12:], s, atol=1e-6)
    np.testing.assert_array_equal(energy.entry_view_cosine(z, None, mask, camera, box), depth_mu)


def test_the_entry_gain_reads_the_normal_pass_where_it_is_given():
    # A surface facing the camera in the Depth pass whose Normal pass says 60 degrees (a normal
    # map, or a mesh too coarse for its depth to show its shading): the view cosine is the
    # normal's, 0.5. "object" keeps the measured level: the light times the entry's gain at 0.5
    # (constant normals and positions: no curvature, so no convex gain; no thickness map).
    args, light = _object_inputs("sphere")
    m = args["mask"]
    tilted = np.broadcast_to(np.float32([0.0, math.sin(math.radians(60.0)), 0.5]), m.shape + (3,)).copy()
    flat = dict(args, depth=np.full(m.shape, 2.0, np.float32), position=np.zeros(m.shape + (3,), np.float32))
    got = energy.apply_energy(light.copy(), **dict(flat, normal=tilted))
    gain = energy.entry_gain("RANDOM_WALK", args["albedo"][m], np.full(m.sum(), 0.5))
    np.testing.assert_allclose(got[m], light[m] * gain, rtol=1e-5)
    # Facing the camera (the Depth pass's cosine, 1) the gain is the table's at normal view.
    facing = np.broadcast_to(np.float32([0.0, 0.0, 1.0]), m.shape + (3,)).copy()
    got = energy.apply_energy(light.copy(), **dict(flat, normal=facing))
    gain = energy.entry_gain("RANDOM_WALK", args["albedo"][m], np.ones(m.sum()))
    np.testing.assert_allclose(got[m], light[m] * gain, rtol=1e-5)


def _passes(h=40, w=40):
    rng = np.random.default_rng(3)
    diffuse = rng.uniform(0.2, 1.0, (h, w, 3)).astype(np.float32)
    albedo = np.broadcast_to(np.array([0.8, 0.5, 0.2], np.float32), (h, w, 3)).copy()
    camera = Camera(width_px=w, height_px=h)
    depth = _plane_depth(camera, 40.0, h, w)
    mask = np.zeros((h, w), bool)
    mask[5:35, 5:35] = True
    return {"diffuse": diffuse, "albedo": albedo, "depth": depth, "mask": mask, "camera": camera}


@pytest.mark.parametrize("technique", [burley, ssss])
def test_techniques_multiply_their_light_on_the_mask_by_the_gain(technique):
    p = _passes()
    d = (0.02, 0.01, 0.005)
    lam = technique(**p, d_su=d, energy="lambert", subsurface_method="RANDOM_WALK")
    obj = technique(**p, d_su=d, subsurface_method="RANDOM_WALK")  # the default, "object"
    view = technique(**p, d_su=d, energy="view", subsurface_method="RANDOM_WALK")
    m = p["mask"]
    mu = energy.view_cosine(p["depth"], m, p["camera"])
    gain = energy.entry_gain("RANDOM_WALK", p["albedo"][m], mu[m])
    # "view": the entry's shape, each channel's total over the mask kept.
    scale = lam[m].astype(np.float64).sum(0) / (lam[m] * gain).astype(np.float64).sum(0)
    np.testing.assert_allclose(view[m], lam[m] * gain * scale.astype(np.float32), rtol=1e-5)
    np.testing.assert_allclose(view[m].astype(np.float64).sum(0), lam[m].astype(np.float64).sum(0), rtol=1e-5)
    # Without a thickness map "object" is "view".
    np.testing.assert_array_equal(obj, view)
    assert np.array_equal(view[~m], lam[~m])
    # Without a method (a direct call), nothing changes.
    assert np.array_equal(technique(**p, d_su=d), lam)
    assert gain.min() < 0.95  # the walk returns visibly less than Lambert at these albedos
    assert gain.max() / gain.min() > 1.02  # and the plane is seen at several angles


def test_pre_post_albedo_mode_reads_the_full_albedo():
    p = _passes()
    m = p["mask"]
    out = np.ones((40, 40, 3), np.float32)
    sqrt_albedo = np.sqrt(p["albedo"])
    got = energy.apply_energy(
        out.copy(),
        diffuse=np.ones_like(out),
        albedo=sqrt_albedo,
        depth=p["depth"],
        mask=m,
        camera=p["camera"],
        subsurface_method="RANDOM_WALK",
        energy="view",
        albedo_mode="pre-post",
    )
    mu = energy.view_cosine(p["depth"], m, p["camera"])[m]
    gain = energy.entry_gain("RANDOM_WALK", p["albedo"][m], mu)  # the full albedo, not its root
    np.testing.assert_allclose(got[m], gain / gain.astype(np.float64).mean(axis=0), rtol=1e-5)


def test_an_unknown_energy_mode_is_refused_by_name():
    p = _passes()
    with pytest.raises(ValueError, match="energy: 'physical' is not one of object, view, lambert"):
        burley(**p, d_su=(0.01, 0.01, 0.01), energy="physical", subsurface_method="RANDOM_WALK")


def test_slab_factors_at_the_nodes_and_beyond():
    for method in sorted(energy.SLAB_ABOVE):
        above = np.array(energy.SLAB_ABOVE[method])
        below = np.array(energy.SLAB_BELOW[method])
        assert above.shape == below.shape == (len(energy.SLAB_ALBEDO), len(energy.SLAB_MFPS))
        j = 2
        a = np.full((len(energy.SLAB_MFPS), 3), energy.SLAB_ALBEDO[j])
        t = np.repeat(np.array(energy.SLAB_MFPS)[:, None], 3, axis=1)
        f_above, f_below = energy.slab_factors(method, a, t)
        np.testing.assert_allclose(f_above[:, 0], above[j] / above[j, -1], rtol=1e-5)
        np.testing.assert_allclose(f_below[:, 0], below[j] / above[j, -1], rtol=1e-5, atol=1e-7)
        # The thickest slab is the semi-infinite medium: nothing lost, nothing through.
        assert f_above[-1, 0] == pytest.approx(1.0) and f_below[-1, 0] == pytest.approx(0.0, abs=1e-3)
        # Thicker than the table reads as its thickest; thinner as its thinnest.
        big, _ = energy.slab_factors(method, a[:1], np.full((1, 3), 1e6))
        small, _ = energy.slab_factors(method, a[:1], np.zeros((1, 3)))
        np.testing.assert_allclose(big, f_above[-1:], rtol=1e-6)
        np.testing.assert_allclose(small, f_above[:1], rtol=1e-6)
    # A random walk loses light through the far side of a thin slab; Christensen-Burley does not
    # (its disk probes find the front surface wherever the slab ends), measured.
    thin = np.full((1, 3), 1.0)
    walk, _ = energy.slab_factors("RANDOM_WALK", np.full((1, 3), 0.8), thin)
    disk, _ = energy.slab_factors("BURLEY", np.full((1, 3), 0.8), thin)
    assert walk.max() < 0.6 and disk.min() > 0.95
    f_above, f_below = energy.slab_factors("UNKNOWN", np.full((1, 3), 0.5), thin)
    assert np.all(f_above == 1) and np.all(f_below == 0)


def _sun(direction, strength=3.0):
    from sss_lab.core.scene.scene import Light

    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    # A sun shines along its local -Z: a rotation taking -Z to d.
    z = -d
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = x, y, z
    return Light(type="SUN", energy=strength, matrix_world=tuple(m.ravel()))


def test_unseen_irradiance_of_a_slab_facing_the_camera():
    # A face whose normal is +Z: the unseen far side faces -Z. A sun from below lights only the far
    # side; one from above only the visible side.
    n = np.tile([0.0, 0.0, 1.0], (16, 1))
    pos = np.zeros((16, 3))
    below = _sun((0.0, 0.0, 1.0))  # shining upwards
    above = _sun((0.0, 0.0, -1.0))
    lamp = 3.0 / math.pi
    e = energy.unseen_irradiance(irradiance=np.zeros((16, 3)), normal=n, position=pos, lights=[below])
    np.testing.assert_allclose(e, lamp, rtol=1e-5)
    # Lit from above, the visible side's measured light is what the lamp explains: nothing unseen.
    e = energy.unseen_irradiance(irradiance=np.full((16, 3), lamp), normal=n, position=pos, lights=[above])
    np.testing.assert_allclose(e, 0.0, atol=1e-6)
    # Light the lamps do not explain (a world) reaches the unseen side alike; without lamps_behind
    # the lamps are left out.
    e = energy.unseen_irradiance(irradiance=np.full((16, 3), lamp + 0.2), normal=n, position=pos, lights=[above, below])
    np.testing.assert_allclose(e, lamp + 0.2, rtol=1e-5)
    e = energy.unseen_irradiance(
        irradiance=np.full((16, 3), lamp + 0.2),
        normal=n,
        position=pos,
        lights=[above, below],
        lamps=False,
    )
    np.testing.assert_allclose(e, 0.2, rtol=1e-4)


def test_the_unseen_side_of_a_box_is_the_face_opposite_each_visible_one():
    # A box seen from above and in front: its top (+Z) and front (-Y) faces are visible, in equal
    # numbers of pixels. What the camera does not see is the bottom (-Z) and the back (+Y). A sun
    # straight from above lights the top only, so nothing unseen; a sun along +Y (from the front)
    # lights the front only, so nothing unseen either; a sun shining along -Y lights the back, one
    # visible face in two (its cosine 1): half its irradiance. (Mirrored across the view direction
    # of a camera in front and a little above, the top would become a back face tilted upwards,
    # lit by the sun from above.)
    n = np.array([[0.0, 0.0, 1.0]] * 8 + [[0.0, -1.0, 0.0]] * 8)
    pos = np.zeros((16, 3))
    zero = np.zeros((16, 3))
    lamp = 3.0 / math.pi
    for direction in ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)):
        e = energy.unseen_irradiance(irradiance=zero, normal=n, position=pos, lights=[_sun(direction)])
        np.testing.assert_allclose(e, 0.0, atol=1e-12)
    e = energy.unseen_irradiance(irradiance=zero, normal=n, position=pos, lights=[_sun((0.0, -1.0, 0.0))])
    np.testing.assert_allclose(e, 0.5 * lamp, rtol=1e-5)


def test_a_thin_slab_lit_from_behind_gets_the_light_through_and_loses_its_own():
    p = _passes()
    h, w = p["mask"].shape
    m = p["mask"]
    d = (0.02, 0.01, 0.005)
    normal = np.zeros((h, w, 3), np.float32)
    normal[..., 2] = 1.0
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    position = np.stack([xs / w, -ys / h, np.zeros_like(xs)], -1)  # a plane: no curvature
    camera = Camera(type="ORTHO", width_px=w, height_px=h, ortho_scale=1.0)
    p = dict(p, camera=camera, depth=np.full((h, w), 2.0, np.float32))
    below = _sun((0.0, 0.0, 1.0))
    ell = (0.004, 0.004, 0.004)
    common = dict(d_su=d, subsurface_method="RANDOM_WALK", normal=normal, position=position, lights=[below])
    common.update(mfp_su=ell, thickness_distance_su=0.04)
    thin = np.full((h, w), 1.0 - (0.004 / 0.04) ** 2, np.float32)  # 4 mm: one mean free path
    thick = np.zeros((h, w), np.float32)  # no far side within D: a flat object's size, CHORD_CAP D
    lam = burley(**p, d_su=d, energy="lambert")
    out_thin = burley(**p, **common, thickness=thin)
    out_thick = burley(**p, **common, thickness=thick)
    # An orthographic camera facing the plane: the entry's gain as measured along the normal.
    gain = energy.entry_gain("RANDOM_WALK", p["albedo"][m], np.ones(m.sum()))
    f_above, f_below = energy.slab_factors("RANDOM_WALK", p["albedo"][m], np.full((m.sum(), 3), 1.0))
    # The sun from below lights only the unseen side; the visible light (random) is more than the
    # lamps explain there, so it counts for the unseen side too.
    unseen = 3.0 / math.pi + p["diffuse"][m].astype(np.float64).mean(axis=0)
    expected = gain * (lam[m] * f_above + p["albedo"][m] * f_below * unseen)
    np.testing.assert_allclose(out_thin[m], expected, rtol=1e-4)
    # 23 mean free paths: almost the semi-infinite medium, almost no light through.
    far = energy.CHORD_CAP * 0.04 / 0.004
    f10, b10 = energy.slab_factors("RANDOM_WALK", p["albedo"][m], np.full((m.sum(), 3), far))
    np.testing.assert_allclose(out_thick[m], gain * (lam[m] * f10 + p["albedo"][m] * b10 * unseen), rtol=1e-4)
    assert np.array_equal(out_thin[~m], lam[~m])


def _ortho_surface(kind, h=48, w=48, radius=0.4):
    """World normal and position passes of a sphere or a cylinder (axis along x) of ``radius``
    seen by an orthographic camera looking down -Z (one scene unit across the image), and the
    mask of the pixels on it (a margin inside the silhouette)."""
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    x = (xs + 0.5 - w / 2) / w
    y = (h / 2 - ys - 0.5) / h
    if kind == "sphere":
        r2 = x * x + y * y
        mask = r2 < (0.9 * radius) ** 2
        z = np.sqrt(np.maximum(radius**2 - r2, 0.0))
        position = np.stack([x, y, z], -1)
        normal = position / radius
    elif kind == "cylinder":
        mask = np.abs(y) < 0.9 * radius
        z = np.sqrt(np.maximum(radius**2 - y * y, 0.0))
        position = np.stack([x, y, z], -1)
        normal = np.stack([np.zeros_like(x), y, z], -1) / radius
    else:
        mask = np.ones((h, w), bool)
        position = np.stack([x, y, np.zeros_like(x)], -1)
        normal = np.broadcast_to([0.0, 0.0, 1.0], position.shape).copy()
    normal[~mask] = 0.0
    return normal.astype(np.float32), position.astype(np.float32), mask


@pytest.mark.parametrize(("kind", "mean", "largest"), [("sphere", 2.5, 2.5), ("cylinder", 1.25, 2.5), ("plane", 0, 0)])
def test_surface_curvature_of_a_sphere_a_cylinder_and_a_plane(kind, mean, largest):
    normal, position, mask = _ortho_surface(kind)
    got_mean, got_largest = energy.surface_curvature(normal, position, mask)
    # Normals that are exactly position / R: every difference gives 1 / R (2.5 per unit) up to
    # float32 rounding of the passes, on an axis across the cylinder, 0 along it.
    np.testing.assert_allclose(got_mean[mask], mean, rtol=2e-3, atol=2e-3)
    np.testing.assert_allclose(got_largest[mask], largest, rtol=2e-3, atol=2e-3)
    assert np.all(got_mean[~mask] == 0) and np.all(got_largest[~mask] == 0)


@pytest.mark.parametrize("method", sorted(energy.CONVEX))
def test_convex_gain_at_its_nodes_flat_and_concave(method):
    table = np.array(energy.CONVEX[method])
    assert table.shape == (len(energy.ALBEDO), len(energy.CONVEX_RADII))
    j = 4
    a = np.full((len(energy.CONVEX_RADII), 3), energy.ALBEDO[j])
    k = np.repeat(1.0 / np.array(energy.CONVEX_RADII)[:, None], 3, axis=1)
    np.testing.assert_allclose(energy.convex_gain(method, a, k)[:, 0], table[j], rtol=1e-5)
    # Flat, concave (not measured) and unknown: 1; more curved than the table: its last column.
    np.testing.assert_allclose(energy.convex_gain(method, a[:2], np.array([[0.0] * 3, [-0.3] * 3])), 1.0)
    np.testing.assert_allclose(energy.convex_gain(method, a[:1], np.full((1, 3), 10.0))[0, 0], table[j, -1], rtol=1e-5)
    assert np.all(energy.convex_gain("UNKNOWN", a, k) == 1.0)


def test_the_convex_gain_is_measured_above_one_for_a_walk():
    # Spheres 8 mean free paths in radius return more light than a flat surface at every albedo
    # below 0.9 (benchmarks/energy.py, --only spheres): a convex surface lets walks out sooner.
    table = np.array(energy.CONVEX["RANDOM_WALK"])
    column = energy.CONVEX_RADII.index(8.0)
    assert np.all(table[np.array(energy.ALBEDO) < 0.9, column] > 1.05)


def _object_inputs(kind, **kw):
    normal, position, mask = _ortho_surface(kind)
    h, w = mask.shape
    rng = np.random.default_rng(5)
    albedo = np.broadcast_to(np.array([0.6, 0.4, 0.2], np.float32), (h, w, 3)).copy()
    diffuse = rng.uniform(0.5, 1.0, (h, w, 3)).astype(np.float32)
    camera = Camera(type="ORTHO", width_px=w, height_px=h, ortho_scale=1.0)
    depth = (2.0 - position[..., 2]).astype(np.float32)
    args = dict(
        diffuse=diffuse,
        albedo=albedo,
        depth=depth,
        mask=mask,
        camera=camera,
        subsurface_method="RANDOM_WALK",
        energy="object",
        albedo_mode="post",
        normal=normal,
        position=position,
        mfp_su=(0.05, 0.05, 0.05),
    )
    args.update(kw)
    return args, albedo * diffuse


def test_object_energy_keeps_the_measured_level_times_the_convex_gain():
    args, light = _object_inputs("sphere")
    m = args["mask"]
    got = energy.apply_energy(light.copy(), **args)
    # The Normal pass gives the view cosine: for the orthographic camera looking down -z, |n_z|.
    n = args["normal"][m].astype(np.float64)
    mu = np.abs(n[:, 2]) / np.linalg.norm(n, axis=1)
    g = energy.entry_gain("RANDOM_WALK", args["albedo"][m], mu)
    mean, _ = energy.surface_curvature(args["normal"], args["position"], m)
    c = energy.convex_gain("RANDOM_WALK", args["albedo"][m], np.repeat(mean[m][:, None] * 0.05, 3, axis=1))
    # The sphere (R = 8 mean free paths): the table's level, not the passes' total.
    np.testing.assert_allclose(got[m], light[m] * g * c, rtol=1e-5)
    assert c.min() > 1.05
    assert np.array_equal(got[~m], light[~m])
    # Without the Normal and Position passes "object" is "view" (each channel's total kept).
    view = energy.apply_energy(light.copy(), **dict(args, normal=None, position=None))
    np.testing.assert_allclose(view[m].astype(np.float64).sum(0), light[m].astype(np.float64).sum(0), rtol=1e-5)


def test_a_map_without_far_side_reads_the_spheres_chord_and_a_thin_shell_is_a_slab():
    args, light = _object_inputs("sphere", thickness_distance_su=0.3)
    m = args["mask"]
    common = dict(args, lights=[])
    no_curvature = dict(
        common, normal=np.tile(np.float32([0, 0, 1]), (*m.shape, 1)), position=np.zeros((*m.shape, 3), np.float32)
    )

    def slab_map(x, distance):
        """The map a slab ``x`` thick reads with bake distance ``distance`` (the slab law)."""
        return np.full(m.shape, 1.0 - (x / distance) ** 2, np.float32)

    cap_map = slab_map(energy.CHORD_CAP * 0.3, 0.9)  # the cap 2.31 D at D = 0.3, read with D = 0.9
    # The map finds no far side within D = 0.3: the sphere's chord 2 R = 0.8 is given (within
    # the cap 2.31 D = 0.69), where a flat surface reads the cap.
    saturated = energy.apply_energy(light.copy(), **dict(common, thickness=np.zeros(m.shape, np.float32)))
    chord = energy.apply_energy(
        light.copy(), **dict(common, thickness=np.zeros(m.shape, np.float32), thickness_distance_su=0.4)
    )
    slab = energy.apply_energy(
        light.copy(),
        **dict(common, thickness=slab_map(0.8, 0.9), thickness_distance_su=0.9),
    )
    np.testing.assert_allclose(chord[m], slab[m], rtol=1e-5)  # 2 / 2.5 = 0.8 <= 2.31 x 0.4
    capped = energy.apply_energy(light.copy(), **dict(common, thickness=cap_map, thickness_distance_su=0.9))
    np.testing.assert_allclose(saturated[m], capped[m], rtol=1e-4)
    flat = energy.apply_energy(light.copy(), **dict(no_curvature, thickness=np.zeros(m.shape, np.float32)))
    flat_cap = energy.apply_energy(light.copy(), **dict(no_curvature, thickness=cap_map, thickness_distance_su=0.9))
    np.testing.assert_allclose(flat[m], flat_cap[m], rtol=1e-4)
    # A shell 0.08 thick on that sphere (a tenth of its chord) keeps a tenth of the convex gain.
    shell = energy.apply_energy(light.copy(), **dict(common, thickness=slab_map(0.08, 0.3)))
    # The Normal pass gives the view cosine: for the orthographic camera looking down -z, |n_z|.
    n = args["normal"][m].astype(np.float64)
    mu = np.abs(n[:, 2]) / np.linalg.norm(n, axis=1)
    g = energy.entry_gain("RANDOM_WALK", args["albedo"][m], mu)
    c = energy.convex_gain("RANDOM_WALK", args["albedo"][m], np.full((m.sum(), 3), 2.5 * 0.05))
    f_above, f_below = energy.slab_factors("RANDOM_WALK", args["albedo"][m], np.full((m.sum(), 3), 0.08 / 0.05))
    # No lamps: the visible light counts for the unseen side (unseen_irradiance).
    unseen = args["diffuse"][m].astype(np.float64).mean(axis=0)
    expected = g * (1 + (c - 1) * 0.1) * (light[m] * f_above + args["albedo"][m] * f_below * unseen)
    np.testing.assert_allclose(shell[m], expected, rtol=2e-3)


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_view_cosine_of_a_window_is_the_frames(kind):
    h, w = 40, 56
    camera = Camera(type=kind, width_px=w, height_px=h, lens_mm=50.0, ortho_scale=1.0)
    z = _plane_depth(camera, 35.0, h, w)
    mask = np.zeros((h, w), bool)
    mask[8:30, 12:50] = True
    full = energy.view_cosine(z, mask, camera)
    window = (slice(6, 33), slice(10, 53))
    part = energy.view_cosine(z[window], mask[window], camera, origin=(6, 10), frame=(h, w))
    np.testing.assert_array_equal(part, full[window])


def test_a_material_below_a_pixel_still_gets_cycles_level():
    import dataclasses

    from sss_lab.core.pipeline.apply import apply
    from sss_lab.core.pipeline.plan import plan
    from sss_lab.core.scene.exr import Passes
    from sss_lab.core.study.synthetic import sphere_scene

    arrays, scene = sphere_scene(96, 64)
    tiny = tuple(
        dataclasses.replace(m, method="RANDOM_WALK", subsurface_scale=m.subsurface_scale * 1e-5) if m.scatters else m
        for m in scene.materials
    )
    scene = dataclasses.replace(scene, materials=tiny)
    passes = Passes(arrays)
    skin = scene.material(2)
    # The kernel is far below a pixel, but Cycles' level of light (the entry's gain) still applies.
    mp = next(m for m in plan(passes, scene, "burley").materials if m.material.index == 2)
    assert mp.skip is None and mp.unchanged_channels == ()
    lam = next(m for m in plan(passes, scene, "burley", energy="lambert").materials if m.material.index == 2)
    assert "at most one pixel" in lam.skip
    out = apply(passes, scene, "burley")["SSSLab.burley.Image"]
    on = np.rint(arrays["Material Index"]) == 2
    light = arrays["Diffuse Color"] * (arrays["Diffuse Direct"] + arrays["Diffuse Indirect"])
    term = out[on, :3] - arrays["Combined"][on, :3]
    # What changed is the light times (gain - 1), the gain within the tables' range for its albedo.
    ratio = (term + light[on, :3]).sum(0) / light[on, :3].sum(0)
    assert skin.method in energy.SEMI_INFINITE
    assert np.all(ratio < 0.99) and np.all(ratio > 0.75)


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
@pytest.mark.parametrize("tilt", [0.0, 60.0, 85.0])
def test_burley_weighs_its_samples_by_the_surface_a_pixel_covers(kind, tilt):
    from sss_lab.core.compute import backend
    from sss_lab.core.optics.surface import MIN_VIEW_COSINE, surface_area

    h, w = 32, 48
    camera = Camera(type=kind, width_px=w, height_px=h, lens_mm=50.0, ortho_scale=1.0)
    z = _plane_depth(camera, tilt, h, w)
    ok = np.zeros((h, w), bool)
    ok[4:28, 6:40] = True
    area = surface_area(z, ok, camera)
    assert np.all(area[~ok] == 1.0) and np.all(area <= 1.0 / MIN_VIEW_COSINE)
    if tilt == 0.0:
        # A plane facing the camera's axis: every pixel covers the surface the pixels' scale says.
        np.testing.assert_allclose(area, 1.0, rtol=1e-6)
    elif tilt < 80:  # (at 85 degrees part of the plane is behind the camera)
        # cos a / cos: the plane's normal n and each pixel's ray r (unit), cos = |n . r|, cos a = |r_z|.
        ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
        if kind == "ORTHO":
            ray = np.broadcast_to([0.0, 0.0, 1.0], (h, w, 3))
        else:
            f = camera.focal_px
            ray = np.stack([(xs + 0.5 - w / 2) / f, (h / 2 - ys - 0.5) / f, -np.ones_like(xs)], -1)
            ray = ray / np.linalg.norm(ray, axis=-1, keepdims=True)
        n = np.array([0.0, math.sin(math.radians(tilt)), math.cos(math.radians(tilt))])
        expected = np.minimum(np.abs(ray[..., 2]) / np.abs(ray @ n), 1.0 / MIN_VIEW_COSINE)
        np.testing.assert_allclose(area[ok], expected[ok], rtol=3e-3)
    # The compiled kernel computes the same (the view cosine rounded to float32 in both).
    got = np.ones((h, w), np.float32)
    if kind == "ORTHO":
        args = (True, float(camera.ortho_px_per_unit), w / 2, h / 2)
    else:
        args = (False, float(camera.focal_px), w / 2, h / 2)
    far = np.float32(1e9)  # the background depth (core.base.arrays.BACKGROUND_DEPTH)
    backend.run_kernel(
        backend.kernels("sss_lab.core.optics").surface_area, z, ok, far, *args, MIN_VIEW_COSINE, 0, h, 0, w, got
    )
    np.testing.assert_allclose(got, area, rtol=1e-6)


def _lamps():
    """A sun, a point, a spot with a soft edge, an area light and a light with no power, coloured."""
    from sss_lab.core.scene.scene import Light

    def at(position, direction):
        m = np.asarray(_sun(direction).matrix_world, np.float64).reshape(4, 4).copy()
        m[:3, 3] = position
        return tuple(m.ravel())

    return [
        _sun((0.3, -0.5, -0.8), strength=2.0),
        Light(type="POINT", energy=40.0, color=(1.0, 0.8, 0.6), matrix_world=at((0.5, 0.4, 1.0), (0, 0, -1))),
        Light(type="SPOT", energy=60.0, spot_blend=0.5, matrix_world=at((-0.4, 0.2, 1.5), (0.2, -0.1, -1.0))),
        Light(type="AREA", energy=30.0, color=(0.5, 0.7, 1.0), matrix_world=at((0.0, -1.0, -0.2), (0.0, 1.0, 0.3))),
        Light(type="POINT", energy=0.0, matrix_world=at((0.0, 0.0, 0.5), (0, 0, -1))),
    ]


@pytest.mark.parametrize("ortho", [False, True])
@pytest.mark.parametrize(("pre_post", "lamps"), [(False, True), (True, True), (False, False)])
def test_the_compiled_unseen_light_is_the_references_within_its_sums(ortho, pre_post, lamps):
    from sss_lab.core.compute import backend
    from sss_lab.core.study.synthetic import sphere_scene

    passes, scene = sphere_scene(40, 30)
    camera = scene.camera
    if ortho:
        camera = Camera(type="ORTHO", width_px=40, height_px=30, ortho_scale=1.0, matrix_world=camera.matrix_world)
    normal = passes["Normal"].copy()
    normal[3, 5] = np.nan  # left out: not finite
    normal[4, 6] = 0.0  # left out: no direction
    position = passes["Position"].astype(np.float64)  # read as float32, as the reference does
    mask = passes["Material Index"] > 1.5
    mask[3, 5] = mask[4, 6] = True
    kw = dict(
        diffuse=passes["Diffuse Direct"] + np.float32(0.05),
        albedo=passes["Diffuse Color"],
        pre_post=pre_post,
        normal=normal,
        position=position,
        lights=_lamps(),
        lamps=lamps,
    )
    with backend.use("numpy"):
        expected = energy.unseen_light(mask, **kw)
    with backend.use("numba"):
        got = energy.unseen_light(mask, **kw)
    # Only the order of the float64 sums differs: within (2 n + 8) u of the terms' mean magnitude
    # (energy._U64's comment), here bounded by their largest: the light's, and each lamp's E_L / pi
    # on the visible and on the reversed unit normal (|N . L| <= 1) times its colour.
    from sss_lab.core.optics.lights import light_at

    n = int(mask.sum()) - 2
    p = passes["Position"][mask]
    lamp = sum(
        2.0 * float(np.max(light_at(light, p[:, 0], p[:, 1], p[:, 2])[3])) / math.pi * max(light.color)
        for light in _lamps()
    )
    e = kw["diffuse"][mask] / (np.maximum(kw["albedo"][mask], np.float32(1e-6)) if pre_post else 1.0)
    magnitude = float(np.abs(e).max()) + lamp
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=(2 * n + 8) * energy._U64 * magnitude)
    assert np.all(np.isfinite(got)) and got.shape == (3,)
    # Check mode runs both and compares them within that bound: a lamp dropped on one side is found.
    with backend.use("check"):
        energy.unseen_light(mask, **kw)
    if lamps:
        original = backend.kernels("sss_lab.core.optics").light_table
        try:
            backend.kernels("sss_lab.core.optics").light_table = lambda lights: original(lights[1:])
            with backend.use("check"), pytest.raises(backend.BackendMismatch, match="unseen_light"):
                energy.unseen_light(mask, **kw)
        finally:
            backend.kernels("sss_lab.core.optics").light_table = original


def test_the_unseen_light_needs_a_pixel_with_a_normal_and_a_position():
    from sss_lab.core.compute import backend
    from sss_lab.core.study.synthetic import sphere_scene

    passes, scene = sphere_scene(16, 12)
    mask = passes["Material Index"] > 1.5
    normal = passes["Normal"].copy()
    normal[mask] = np.nan
    kw = dict(
        diffuse=passes["Diffuse Direct"],
        albedo=passes["Diffuse Color"],
        pre_post=False,
        normal=normal,
        position=passes["Position"],
        lights=_lamps(),
        lamps=True,
    )
    for mode in ("numpy", "numba", "check"):
        with backend.use(mode):
            assert energy.unseen_light(mask, **kw) is None


@pytest.mark.parametrize(
    ("method", "pre_post", "convention", "lights"),
    [
        ("RANDOM_WALK", False, "translucency", True),
        ("RANDOM_WALK_SKIN", True, "thickness", True),
        ("RANDOM_WALK_LEGACY", False, "translucency", False),
        ("CHRISTENSEN_BURLEY", False, "translucency", True),
    ],
)
def test_the_compiled_object_light_is_the_references_to_the_bit(method, pre_post, convention, lights):
    """``apply_energy``'s "object" light on the compiled backend (``core.optics._kernels.energy_object``)
    against the NumPy reference, every value equal: maps with NaN, +-inf, no far side and values
    beyond 0..1, a mask with a hole, albedos beyond the tables, each subsurface method (Christensen-
    Burley has no table: its light stays), both thickness conventions and albedo modes, with and
    without lamps; and without a thickness map (no slab)."""
    from sss_lab.core.compute import backend

    args, light = _object_inputs("sphere", thickness_distance_su=0.3)
    m = args["mask"].copy()
    m[m.shape[0] // 2, m.shape[1] // 2] = False  # a hole
    h, w = m.shape
    rng = np.random.default_rng(11)
    thickness = rng.uniform(-0.2, 1.2, (h, w)).astype(np.float32)
    thickness[rng.uniform(size=(h, w)) < 0.2] = 0.0  # no far side: the chord
    thickness[2, :] = np.nan
    thickness[3, ::2], thickness[3, 1::2] = np.inf, -np.inf
    albedo = rng.uniform(0.0, 1.0, (h, w, 3)).astype(np.float32)
    args = dict(
        args,
        mask=m,
        albedo=albedo,
        subsurface_method=method,
        albedo_mode="pre-post" if pre_post else "post",
        thickness=thickness,
        thickness_convention=convention,
        lights=_lamps() if lights else [],
    )
    for kw in (args, dict(args, thickness=None)):
        with backend.use("numpy"):
            expected = energy.apply_energy(light.copy(), **kw)
        with backend.use("numba"):
            got = energy.apply_energy(light.copy(), **kw)
        np.testing.assert_array_equal(got, expected)
        assert not np.array_equal(expected[m], light[m]) or method == "CHRISTENSEN_BURLEY"


def test_check_mode_finds_a_compiled_object_light_that_differs():
    """Check mode compares the compiled "object" light with the reference's with bound 0: one
    pixel's last bit changed is found."""
    from sss_lab.core.compute import backend

    args, light = _object_inputs("sphere", thickness_distance_su=0.3, thickness=None)
    with backend.use("check"):
        energy.apply_energy(light.copy(), **args)
    kernels = backend.kernels("sss_lab.core.optics")
    original = kernels.energy_object

    def one_bit_off(out, *rest):
        original(out, *rest)
        y, x = np.argwhere(args["mask"])[0]
        out[y, x, 0] = np.nextafter(out[y, x, 0], np.float32(np.inf))

    try:
        kernels.energy_object = one_bit_off
        with backend.use("check"), pytest.raises(backend.BackendMismatch, match="energy"):
            energy.apply_energy(light.copy(), **args)
    finally:
        kernels.energy_object = original
