"""The engines' profile values (``core/study/profile_export.py``) and the bakers' thickness map,
held to the formulas of docs/references.md §19 written out here, without Blender."""

from __future__ import annotations

import math
import struct
import zlib

import numpy as np
import pytest

from sss_lab.core.scene import thickness
from sss_lab.core.study import png
from sss_lab.core.study import profile_export as pe

D_SU = np.array([0.0041, 0.0017, 0.0009])  # scene units
ALBEDO = (0.82, 0.55, 0.41)


def _burley_cdf(x):
    """1 - e^-x / 4 - 3 e^(-x/3) / 4, the profile's energy within x d (§1)."""
    return 1 - math.exp(-x) / 4 - 3 * math.exp(-x / 3) / 4


@pytest.mark.parametrize("metres", [1.0, 0.01, 2.5])
def test_hdrp_scattering_distance_is_d_in_millimetres_as_colour_times_multiplier(metres):
    p = pe.hdrp_profile(D_SU, metres_per_unit=metres, albedo_mode="post", thickness_distance_su=0.02)
    d_mm = D_SU * metres * 1000
    np.testing.assert_allclose(np.array(p["scatteringDistance"]) * p["scatteringDistanceMultiplier"], d_mm, rtol=1e-12)
    assert max(p["scatteringDistance"]) == pytest.approx(1.0)
    assert p["worldScale"] == pytest.approx(metres)  # HDRP: the size of one unit in metres
    assert p["texturingMode"] == "PostScatter"
    np.testing.assert_allclose(p["thicknessRemap"], [0.0, 0.02 * metres * 1000], rtol=1e-12)
    # Max Radius: the 99.7 % energy radius of the widest channel, in mm.
    assert _burley_cdf(p["max_radius_mm"] / d_mm.max()) == pytest.approx(0.997, abs=1e-9)
    assert p["max_radius_mm"] / d_mm.max() == pytest.approx(16.56, abs=0.01)
    np.testing.assert_allclose(pe.d_from_hdrp(p, metres_per_unit=metres), D_SU, rtol=1e-12)


def test_hdrp_pre_post_mode_unknown_thickness_and_tiny_units_are_said():
    p = pe.hdrp_profile(D_SU, metres_per_unit=1e-4, albedo_mode="pre-post")
    assert p["texturingMode"] == "PreAndPostScatter"
    assert p["thicknessRemap"] is None
    assert p["worldScale"] == pe.HDRP_MIN_WORLD_SCALE
    assert any("World Scale is at least" in n for n in p["notes"])
    assert any("no baked thickness distance" in n for n in p["notes"])
    with pytest.raises(ValueError, match="albedo_mode: expected one of post, pre-post, got 'pre'"):
        pe.hdrp_profile(D_SU, metres_per_unit=1.0, albedo_mode="pre")
    with pytest.raises(ValueError, match="metres_per_unit: expected a number > 0"):
        pe.hdrp_profile(D_SU, metres_per_unit=0.0)
    with pytest.raises(ValueError, match="d_su: expected three finite lengths"):
        pe.hdrp_profile((1.0, float("nan"), 1.0), metres_per_unit=1.0)


@pytest.mark.parametrize("metres", [1.0, 3.0])
def test_unreal_mean_free_path_follows_the_perpendicular_scaling_in_centimetres(metres):
    p = pe.unreal_profile(D_SU, ALBEDO, metres_per_unit=metres)
    s_perp = np.array([1.85 - a + 7 * abs(a - 0.8) ** 3 for a in ALBEDO])
    mfp_cm = 0.6 * s_perp * D_SU * metres * 100
    np.testing.assert_allclose(p["mean_free_path_cm"], mfp_cm, rtol=1e-12)
    written = np.array(p["mean_free_path_color"]) * p["mean_free_path_distance"] * p["world_unit_scale"] / 0.1
    np.testing.assert_allclose(written, mfp_cm, rtol=1e-12)
    assert p["enable_burley"] and p["enable_mean_free_path"]  # else Unreal's loader converts the values again
    np.testing.assert_allclose(p["surface_albedo"], ALBEDO)
    np.testing.assert_allclose(pe.d_from_unreal(p, metres_per_unit=metres), D_SU, rtol=1e-12)


def test_unreal_long_paths_move_into_world_unit_scale_and_short_ones_are_said():
    long = pe.unreal_profile(D_SU * 400, ALBEDO, metres_per_unit=1.0)  # metres of scattering
    assert long["mean_free_path_distance"] == pe.UNREAL_DISTANCE_CM[1]
    assert long["world_unit_scale"] > pe.UNREAL_UNIT_SCALE
    np.testing.assert_allclose(pe.d_from_unreal(long, metres_per_unit=1.0), D_SU * 400, rtol=1e-12)
    assert long["notes"] == []
    short = pe.unreal_profile(D_SU / 100, ALBEDO, metres_per_unit=1.0)
    assert short["mean_free_path_distance"] == pe.UNREAL_DISTANCE_CM[0]
    assert any("below Unreal's smallest distance" in n for n in short["notes"])
    # What Unreal will render is wider than the material's, and the round trip says by how much.
    assert np.all(pe.d_from_unreal(short, metres_per_unit=1.0) > D_SU / 100)
    dark = pe.unreal_profile(D_SU, (0.0, 0.5, 1.2), metres_per_unit=1.0)
    assert dark["surface_albedo"] == [0.01, 0.5, 1.0]
    assert any("Surface Albedo clamped" in n for n in dark["notes"])


def test_eevee_inputs_give_back_d_through_eevees_own_reading():
    e = pe.eevee_inputs(D_SU, ALBEDO, scale=0.05)
    assert e["subsurface_scale"] == 0.05
    s = np.array([1.9 - a + 3.5 * (a - 0.8) ** 2 for a in ALBEDO])
    np.testing.assert_allclose(np.array(e["subsurface_radius"]) * 0.05 / (4 * math.pi) / s, D_SU, rtol=1e-12)
    np.testing.assert_allclose(pe.d_from_eevee(e, ALBEDO), D_SU, rtol=1e-12)


def test_material_export_and_its_page_carry_every_engine_and_the_gain():
    m = pe.material_export(
        "Wax",
        d_su=D_SU,
        base_color=ALBEDO,
        subsurface_scale=0.05,
        metres_per_unit=1.0,
        thickness_distance_su=0.03,
        gain=(1.1, 0.9, 0.8),
        source="test",
    )
    assert m["base_color_gain"] == [1.1, 0.9, 0.8]
    np.testing.assert_allclose(m["d_mm"], D_SU * 1000)
    text = pe.page(
        {"scene": "S", "metres_per_unit": 1.0, "albedo_mode": "post", "technique": "burley", "materials": [m]}
    )
    assert "## Wax" in text
    assert f"{m['hdrp']['scatteringDistanceMultiplier']:.4g}" in text
    assert f"{m['unreal']['mean_free_path_distance']:.4g}" in text
    assert "0, 30" in text  # the thickness remap in mm


def test_bakers_map_is_the_slab_thickness_over_the_distance_white_thick():
    d = 0.2
    t = np.array([[0.0, 0.05], [0.1, 0.3]])  # slab thicknesses, the last beyond D
    ao = thickness.slab_unoccluded_fraction(t, d)
    for convention in thickness.CONVENTIONS:
        baked = thickness.to_convention(ao, convention)
        np.testing.assert_allclose(thickness.bakers_map(baked, convention), np.minimum(t / d, 1), atol=1e-6)
        np.testing.assert_allclose(thickness.object_thickness_su(baked, convention, d), np.minimum(t, d), atol=1e-6)
    with pytest.raises(ValueError, match=r"expected a baked map in 0..1, got values in -0.1..1"):
        thickness.bakers_map(np.array([-0.1, 1.0]), "thickness")
    with pytest.raises(ValueError, match="distance_su: expected the bake distance"):
        thickness.object_thickness_su(ao, "thickness", 0.0)


def test_png16_gray_round_trips_through_a_plain_decoder():
    values = np.array([[0.0, 0.25, 1.0], [0.5, 1 / 65535, 0.75]])
    data = png.encode_png16_gray(values)
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    w, h, depth, colour = struct.unpack(">IIBB", data[16:26])
    assert (w, h, depth, colour) == (3, 2, 16, 0)
    length = struct.unpack(">I", data[33:37])[0]
    raw = zlib.decompress(data[41 : 41 + length])
    rows = np.frombuffer(raw, np.uint8).reshape(2, 1 + 6)
    assert np.all(rows[:, 0] == 0)  # filter type none
    decoded = rows[:, 1:].copy().view(">u2").astype(np.float64) / 65535
    np.testing.assert_allclose(decoded, values, atol=0.5 / 65535)
    with pytest.raises(ValueError, match="expected finite values in 0..1"):
        png.encode_png16_gray(np.array([[1.5]]))
