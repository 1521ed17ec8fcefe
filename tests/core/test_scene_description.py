"""The scene description: validation, JSON round trip, and the camera footprint maths."""

import math

import numpy as np
import pytest

from sss_lab.core.scene.scene import Camera, Light, MaterialSSS, SceneDescription


def test_json_round_trip_keeps_everything():
    scene = SceneDescription(
        camera=Camera(type="ORTHO", width_px=64, height_px=32, ortho_scale=2.0),
        lights=(Light(type="SPOT", name="Key", energy=100.0, spot_size=0.5, spot_blend=0.2),),
        materials=(MaterialSSS(index=1, name="Skin", method="BURLEY", base_color=(0.8, 0.5, 0.4)),),
        frame=7,
        meta={"samples": 16},
    )
    again = SceneDescription.from_json(scene.to_json())
    assert again == scene


def test_perspective_footprint_is_focal_length_over_depth():
    # 50 mm lens on a 36 mm sensor, horizontal fit over 1000 px: focal length 1388.9 px.
    cam = Camera(type="PERSP", width_px=1000, height_px=500, lens_mm=50.0, sensor_width_mm=36.0)
    depth = np.array([[1.0, 2.0, 1e10]], dtype=np.float32)
    ppu = cam.pixels_per_unit(depth)
    assert ppu[0, 0] == pytest.approx(50.0 / 36.0 * 1000.0, rel=1e-6)
    assert ppu[0, 1] == pytest.approx(ppu[0, 0] / 2.0, rel=1e-6)
    assert ppu[0, 2] < 1e-6  # background: no footprint


def test_auto_fit_uses_the_larger_dimension_for_portrait_images():
    cam = Camera(type="PERSP", width_px=500, height_px=1000, lens_mm=36.0, sensor_width_mm=36.0)
    assert cam.focal_px == pytest.approx(1000.0)


def test_orthographic_footprint_is_constant():
    cam = Camera(type="ORTHO", width_px=200, height_px=100, ortho_scale=4.0)
    ppu = cam.pixels_per_unit(np.array([[0.5, 3.0]], dtype=np.float32))
    np.testing.assert_allclose(ppu, 50.0)


def test_view_vectors_point_to_the_camera():
    m = np.eye(4)
    m[:3, 3] = (0.0, 0.0, 5.0)
    cam = Camera(matrix_world=tuple(m.ravel()))
    pos = np.zeros((1, 2, 3), dtype=np.float32)
    pos[0, 1] = (3.0, 0.0, 1.0)
    v = cam.view_vectors(pos)
    np.testing.assert_allclose(v[0, 0], (0.0, 0.0, 1.0), atol=1e-6)
    np.testing.assert_allclose(v[0, 1], np.array([-3.0, 0.0, 4.0]) / 5.0, atol=1e-6)


@pytest.mark.parametrize(
    ("factory", "message"),
    [
        (lambda: Camera(type="PANO"), "PANO"),
        (lambda: Camera(width_px=0), "width_px"),
        (lambda: Camera(lens_mm=-1.0), "lens_mm"),
        (lambda: Light(type="LASER"), "LASER"),
        (lambda: Light(type="SPOT", spot_size=4.0), "spot_size"),
        (lambda: MaterialSSS(index=0), "index"),
        (lambda: MaterialSSS(index=1, method="DIPOLE"), "DIPOLE"),
        (lambda: MaterialSSS(index=1, subsurface_radius=(1.0, -0.2, 0.1)), "subsurface_radius"),
        (lambda: MaterialSSS(index=1, base_color=(1.0, math.nan, 0.0)), "base_color"),
    ],
)
def test_bad_values_are_named(factory, message):
    with pytest.raises(ValueError, match=message):
        factory()


def test_version_mismatch_is_rejected():
    data = SceneDescription(camera=Camera()).to_dict()
    data["version"] = 999
    with pytest.raises(ValueError, match="version"):
        SceneDescription.from_dict(data)


def test_scattering_needs_weight_scale_and_radius():
    assert MaterialSSS(index=1).scatters
    assert not MaterialSSS(index=1, subsurface_weight=0.0).scatters
    assert not MaterialSSS(index=1, subsurface_radius=(0.0, 0.0, 0.0)).scatters
    assert MaterialSSS(index=1, subsurface_scale=0.01).radius == pytest.approx((0.01, 0.002, 0.001))


def test_a_materials_notes_are_strings_kept_as_a_tuple():
    from sss_lab.core.scene.scene import MaterialSSS

    assert MaterialSSS(index=1, notes=["a", "b"]).notes == ("a", "b")
    with pytest.raises(ValueError, match="notes: expected a list of strings"):
        MaterialSSS(index=1, name="Skin", notes="not a list")
    with pytest.raises(ValueError, match="notes: expected a list of strings"):
        MaterialSSS(index=1, notes=(1,))


def test_a_subsurface_weight_above_one_is_refused_by_name():
    """Cycles' Subsurface Weight is a mix factor: a description saying 2 is damaged or hand-edited."""
    import pytest

    from sss_lab.core.scene.scene import MaterialSSS

    with pytest.raises(ValueError, match=r"material 'Wax' subsurface_weight: expected a number in 0..1, got 2.0"):
        MaterialSSS(index=1, name="Wax", subsurface_weight=2.0)
    assert MaterialSSS(index=1, name="Wax", subsurface_weight=1.0).scatters


def test_a_thickness_aov_naming_a_render_pass_is_refused():
    """A description whose thickness AOV names the Depth pass would read depth as thickness."""
    import pytest

    from sss_lab.core.scene.scene import Camera, SceneDescription

    camera = Camera(width_px=8, height_px=8)
    for name in ("Depth", "Normal", "IndexMA"):
        with pytest.raises(ValueError, match=rf"thickness_aov: '{name}' is a render pass of Blender's"):
            SceneDescription(camera=camera, thickness_aov=name)
    assert SceneDescription(camera=camera, thickness_aov="Thickness").thickness_aov == "Thickness"
