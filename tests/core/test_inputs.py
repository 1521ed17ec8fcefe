"""Per-pixel subsurface inputs read back from their shader AOVs (core/scene/inputs.py) and the
Subsurface Weight mix in apply, on the analytic plane-and-spheres scene of core/study/synthetic.py."""

import dataclasses

import numpy as np
import pytest

from sss_lab.core.pipeline.apply import apply
from sss_lab.core.pipeline.plan import plan
from sss_lab.core.scene.exr import Passes
from sss_lab.core.scene.inputs import interior, measure, measured_scene, weight_map
from sss_lab.core.scene.passes import INPUT_AOVS
from sss_lab.core.scene.scene import MaterialSSS, SceneDescription
from sss_lab.core.study.synthetic import sphere_scene

SCALE_AOV = INPUT_AOVS["subsurface_scale"].name
COLOR_AOV = INPUT_AOVS["base_color"].name
WEIGHT_AOV = INPUT_AOVS["subsurface_weight"].name


def _with(scene: SceneDescription, index: int, **changes) -> SceneDescription:
    materials = tuple(dataclasses.replace(m, **changes) if m.index == index else m for m in scene.materials)
    return dataclasses.replace(scene, materials=materials)


@pytest.fixture
def sphere():
    arrays, scene = sphere_scene()
    return arrays, scene


def test_interior_drops_the_edge_and_keeps_a_small_mask_whole():
    mask = np.zeros((10, 10), bool)
    mask[2:8, 2:8] = True
    inner = interior(mask)
    assert inner.sum() == 16 and inner[3:7, 3:7].all()  # 6 x 6 -> 4 x 4
    small = np.zeros((10, 10), bool)
    small[0:4, 0:4] = True  # 16 pixels, touching the image's border: too few would stay
    assert interior(small) is small


def test_medians_skip_nan_read_negatives_as_zero_and_say_so(sphere):
    arrays, scene = sphere
    index = 2
    mask = np.rint(arrays["Material Index"]) == index
    inner = interior(mask)
    rng = np.random.default_rng(0)
    scale = np.where(mask, rng.uniform(0.01, 0.03, mask.shape), 0.0).astype(np.float32)
    rows, cols = np.nonzero(inner)
    scale[rows[:5], cols[:5]] = np.nan
    scale[rows[5:8], cols[5:8]] = -1.0
    color = np.zeros(mask.shape + (4,), np.float32)
    color[mask] = (0.4, 1.7, 0.2, 1.0)  # green above 1: Cycles clamps Base Color to 1
    passes = Passes({**arrays, SCALE_AOV: scale, COLOR_AOV: color})
    material = dataclasses.replace(scene.material(index), per_pixel=("subsurface_scale", "base_color"))
    got = measure(material, passes, mask)
    kept = scale[inner]
    kept = np.maximum(kept[np.isfinite(kept)], 0.0)
    assert got.subsurface_scale == pytest.approx(float(np.median(kept)))
    assert got.base_color == pytest.approx((0.4, 1.0, 0.2))
    assert got.measured and got.per_pixel == material.per_pixel
    note = next(n for n in got.notes if n.startswith("Subsurface Scale"))
    assert f"over {kept.size} pixels" in note
    assert "5 pixels NaN or infinite left out" in note and "3 pixels negative, read as 0" in note


def test_an_aov_without_a_finite_value_or_missing_keeps_the_socket_value(sphere):
    arrays, scene = sphere
    index = 2
    mask = np.rint(arrays["Material Index"]) == index
    material = dataclasses.replace(scene.material(index), per_pixel=("subsurface_scale", "base_color"))
    passes = Passes({**arrays, SCALE_AOV: np.full(mask.shape, np.nan, np.float32)})
    got = measure(material, passes, mask)
    assert got.subsurface_scale == material.subsurface_scale and got.base_color == material.base_color
    assert any("holds no finite value" in n and "socket's value" in n for n in got.notes)
    assert any(f"the passes have no {COLOR_AOV!r} AOV" in n for n in got.notes)


def test_measured_scene_is_free_without_per_pixel_inputs(sphere):
    arrays, scene = sphere
    passes = Passes(arrays)
    masks = {m.index: np.rint(arrays["Material Index"]) == m.index for m in scene.materials}
    assert measured_scene(passes, scene, masks) is scene


def test_plan_uses_the_measured_values(sphere):
    """The plan's kernel follows the Scale the render wrote, not the socket's value."""
    arrays, scene = sphere
    index = 2
    socket = scene.material(index).subsurface_scale
    mask = np.rint(arrays["Material Index"]) == index
    scale = np.where(mask, 2.0 * socket, 0.0).astype(np.float32)
    passes = Passes({**arrays, SCALE_AOV: scale})
    typed = plan(Passes(arrays), scene, "burley")
    linked = plan(passes, _with(scene, index, per_pixel=("subsurface_scale",)), "burley")
    before = next(mp for mp in typed.materials if mp.material.index == index)
    after = next(mp for mp in linked.materials if mp.material.index == index)
    assert after.material.subsurface_scale == pytest.approx(2.0 * socket)
    assert after.kernel_su == pytest.approx(tuple(2.0 * r for r in before.kernel_su))
    assert "read from the render" in linked.explain()


@pytest.mark.parametrize("technique", ["burley", "ssss", "sta"])
def test_a_subsurface_weight_scales_the_technique_term(sphere, technique):
    """Cycles mixes (1 - w) diffuse + w subsurface at the pixel it sees: the SSS term at weight w is
    w times the term at weight 1 (to float32 rounding: the product is taken before the subtraction
    of the light Combined held)."""
    arrays, scene = sphere
    passes = Passes(arrays)
    full = apply(passes, scene, technique)[f"SSSLab.{technique}.SSS"]
    index = 2
    half = apply(passes, _with(scene, index, subsurface_weight=0.5), technique)[f"SSSLab.{technique}.SSS"]
    mask = np.rint(arrays["Material Index"]) == index
    assert np.abs(full[mask]).max() > 0
    np.testing.assert_allclose(half[mask], 0.5 * full[mask], rtol=1e-5, atol=1e-6 * np.abs(full).max())
    np.testing.assert_array_equal(half[~mask], full[~mask])  # the other materials as they were


def test_a_per_pixel_weight_mixes_each_pixel(sphere):
    """A Weight AOV of 0 on the left half of a material and 1 on the right: the left keeps Combined
    to the bit, the right gets the whole term (its edge takes the material's weight)."""
    arrays, scene = sphere
    index = 3
    mask = np.rint(arrays["Material Index"]) == index
    cols = np.nonzero(mask)[1]
    middle = (cols.min() + cols.max()) // 2
    weight = np.zeros(mask.shape, np.float32)
    weight[:, middle:] = 1.0
    passes = Passes({**arrays, WEIGHT_AOV: weight})
    linked = _with(scene, index, per_pixel=("subsurface_weight",))
    w = weight_map(linked.material(index), passes, mask)
    inner = interior(mask)
    np.testing.assert_array_equal(w[inner], weight[inner])
    full = apply(Passes(arrays), scene, "burley")["SSSLab.burley.SSS"]
    got = apply(passes, linked, "burley")["SSSLab.burley.SSS"]
    left, right = inner & (weight == 0), inner & (weight == 1)
    assert left.any() and right.any()
    assert not np.any(got[left])
    np.testing.assert_array_equal(got[right], full[right])


def test_per_pixel_round_trips_and_rejects_unknown_inputs():
    m = MaterialSSS(index=1, name="Skin", per_pixel=("base_color", "subsurface_scale"), measured=False)
    arrays, scene = sphere_scene()
    desc = dataclasses.replace(scene, materials=(m,))
    back = SceneDescription.from_json(desc.to_json())
    assert back.materials[0].per_pixel == ("base_color", "subsurface_scale")
    with pytest.raises(ValueError, match=r"per_pixel: expected a list of some of base_color.*'roughness'"):
        MaterialSSS(index=1, name="Skin", per_pixel=("roughness",))


def test_a_scale_that_varies_gives_each_pixel_its_own_d(sphere):
    """A Scale AOV of s on the left half of a sphere and 3 s on the right: the plan splits the
    material into zones by d, and each half's interior gets what the material with its own Scale
    typed in gets there (the zone gathers from the whole material, as the typed-in one does)."""
    from sss_lab.core.pipeline.zones import ZONES

    arrays, scene = sphere
    index = 2
    material = scene.material(index)
    mask = np.rint(arrays["Material Index"]) == index
    cols = np.nonzero(mask)[1]
    middle = (cols.min() + cols.max()) // 2
    s = material.subsurface_scale
    scale = np.where(np.arange(mask.shape[1])[None, :] < middle, s, 3 * s) * np.ones(mask.shape)
    passes = Passes({**arrays, SCALE_AOV: scale.astype(np.float32)})
    linked = _with(scene, index, per_pixel=("subsurface_scale",))
    p = plan(passes, linked, "burley")
    mp = next(m for m in p.materials if m.material.index == index)
    assert 2 <= len(mp.zones) <= ZONES
    assert "computed in" in p.explain() and "zones by their own d" in p.explain()
    got = apply(passes, linked, "burley", prepared=p)["SSSLab.burley.SSS"]
    inner = interior(mask)
    for part, factor in ((inner & (scale == s), 1.0), (inner & (scale == 3 * s), 3.0)):
        typed = _with(scene, index, subsurface_scale=factor * s)
        want = apply(Passes(arrays), typed, "burley")["SSSLab.burley.SSS"]
        assert part.any()
        np.testing.assert_allclose(got[part], want[part], rtol=1e-4, atol=1e-6 * np.abs(want).max())
    assert np.all(np.isfinite(got)) and np.any(got[mask & ~inner])  # the silhouette is computed too


def test_a_scale_that_barely_varies_stays_one_zone(sphere):
    arrays, scene = sphere
    index = 2
    s = scene.material(index).subsurface_scale
    rng = np.random.default_rng(1)
    scale = (s * rng.uniform(0.98, 1.02, arrays["Depth"].shape)).astype(np.float32)
    p = plan(Passes({**arrays, SCALE_AOV: scale}), _with(scene, index, per_pixel=("subsurface_scale",)), "burley")
    assert not next(m for m in p.materials if m.material.index == index).zones
