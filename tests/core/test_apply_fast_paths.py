"""The short cuts core/pipeline/apply.py and core/pipeline/plan.py take on the usual, all-finite passes give the same
bits as the plain formulation: a finiteness test by a float sum, no cleaning copy of a finite pass,
the diffuse light Combined holds taken on the material's box, one comparison per listed Material
Index instead of sorting the map. The reference below is written out the long way, with boolean
indexing, and compared to the bit on passes with NaN, +-inf and negative values in every pass."""

import inspect
import math

import numpy as np
import pytest

from sss_lab.core.base import arrays as _arrays
from sss_lab.core.pipeline.apply import apply
from sss_lab.core.pipeline.plan import plan
from sss_lab.core.scene.exr import Passes
from sss_lab.core.scene.extent import mask_extent_px
from sss_lab.core.study.synthetic import sphere_scene
from sss_lab.core.techniques.registry import TECHNIQUES

F32_MAX = np.finfo(np.float32).max


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, "inf and -inf"], ids=["nan", "+inf", "-inf", "inf and -inf"])
@pytest.mark.parametrize("shape", [(7,), (5, 9), (4, 6, 3)])
def test_all_finite_finds_any_non_finite_value(shape, bad):
    rng = np.random.default_rng(1)
    a = rng.normal(size=shape).astype(np.float32)
    assert _arrays.all_finite(a)
    for flat in (0, a.size // 2, a.size - 1):
        b = a.copy().reshape(-1)
        if bad == "inf and -inf":  # their sum is NaN
            b[flat], b[(flat + 1) % b.size] = np.inf, -np.inf
        else:
            b[flat] = bad
        assert not _arrays.all_finite(b.reshape(shape))


def test_all_finite_is_true_when_finite_values_overflow_their_sum():
    a = np.full((64, 64, 3), F32_MAX, np.float32)
    a[::2] = -F32_MAX
    a[0, 0, 0] = F32_MAX  # the float32 sum overflows (its pairs of +-max add to +-inf) ...
    with np.errstate(over="ignore", invalid="ignore"):
        assert not np.isfinite(np.add.reduce(a, axis=None))
    assert _arrays.all_finite(a)  # ... yet every value is finite
    a[5, 7, 1] = np.nan
    assert not _arrays.all_finite(a)
    assert _arrays.all_finite(np.zeros((0, 3), np.float32))
    # A strided view (the RGB of an RGBA pass): its own values only.
    rgba = np.ones((4, 5, 4), np.float32)
    rgba[..., 3] = np.inf
    assert _arrays.all_finite(rgba[..., :3]) and not _arrays.all_finite(rgba)


def _listed_extent(m: np.ndarray) -> float:
    """The extent from the mask's pixels listed (how it was computed before the bounding box)."""
    ys, xs = np.nonzero(m)
    return 0.0 if ys.size == 0 else math.hypot(float(xs.max() - xs.min()), float(ys.max() - ys.min())) + 1.0


def test_box_extent_is_the_mask_extent():
    rng = np.random.default_rng(2)
    for _ in range(20):
        m = rng.random((23, 31)) < rng.choice([0.0, 0.002, 0.05, 0.5])
        assert mask_extent_px(m) == _listed_extent(m)


def _index_reference(mi: np.ndarray) -> np.ndarray:
    out = np.full(mi.shape, -1, np.int64)
    finite = np.isfinite(mi)
    out[finite] = np.rint(mi[finite]).astype(np.int64)
    return out


def test_plan_counts_each_index_as_sorting_the_map_does():
    arrays, scene = sphere_scene()
    mi = arrays["Material Index"].copy()
    mi[0, :8] = [np.nan, np.inf, -np.inf, 7.0, 7.4, 2.5, 3.5, -2.0]  # 2.5 -> 2, 3.5 -> 4 (round half even)
    mi[1, :3] = [0.0, 9.0, 1e6]
    with np.errstate(invalid="ignore"):
        p = plan(Passes({**arrays, "Material Index": mi}), scene, "burley")
    index = _index_reference(mi)
    values, counts = np.unique(index[index > 0], return_counts=True)
    every = dict(zip(values.tolist(), counts.tolist(), strict=True))
    for mp in p.materials:
        assert mp.pixels == every.get(mp.material.index, 0)
    known = {m.index for m in scene.materials}
    assert p.unknown_indices == {i: c for i, c in every.items() if i not in known}
    assert set(p.unknown_indices) == {4, 7, 9, 1000000}
    # Without unlisted indices the map is not sorted, and none is reported.
    assert plan(Passes(arrays), scene, "burley").unknown_indices == {}


def _fin(a: np.ndarray) -> np.ndarray:
    return np.isfinite(a).all(axis=-1) if a.ndim == 3 else np.isfinite(a)


def _clean(a: np.ndarray) -> np.ndarray:
    a = np.array(a, np.float32)
    a[~np.isfinite(a)] = 0.0
    return a


_KEYWORDS = {"Normal": "normal", "Position": "position", "Object Index": "object_id", "Thickness": "thickness"}


def _reference(passes: Passes, scene, technique: str):
    """apply's documented result, the long way: every input cleaned, masks by boolean indexing."""
    p = plan(passes, scene, technique)
    spec = p.spec
    rgb = passes["Combined"][..., :3]
    ok = _fin(passes["Diffuse Color"]) & _fin(rgb)
    inputs = {
        "albedo": _clean(passes["Diffuse Color"]),
        "camera": scene.camera,
        "lights": scene.lights,
        "thickness_convention": scene.thickness_convention,
    }
    for name in spec.passes + tuple(n for n in spec.optional_passes if n in passes.names):
        if name in _KEYWORDS:
            raw = passes[name]
            if name != "Object Index":
                ok &= _fin(raw)
            inputs[_KEYWORDS[name]] = _clean(raw[..., 0] if name == "Thickness" and raw.ndim == 3 else raw)
    held = None
    if spec.scatters:
        direct, indirect, depth = passes["Diffuse Direct"], passes["Diffuse Indirect"], passes["Depth"]
        ok &= _fin(direct) & _fin(indirect) & _fin(depth)
        diffuse = _clean(direct) + _clean(indirect)
        held = inputs["albedo"] * diffuse
        inputs["diffuse"] = diffuse
        inputs["depth"] = np.where(np.isfinite(depth), depth, np.float32(1e10)).astype(np.float32)
    image = np.array(passes["Combined"], np.float32)
    sss = np.zeros(rgb.shape, np.float32)
    index = _index_reference(passes["Material Index"])
    takes = set(inspect.signature(spec.function).parameters)
    nonfinite = 0
    for mp in p.applied:
        mask = index == mp.material.index
        nonfinite += int((mask & ~ok).sum())
        mask &= ok
        params = dict(mp.params)
        gain = None if "gain" in takes else params.pop("gain", None)
        kwargs = {k: v for k, v in {**inputs, **params, "mask": mask}.items() if k in takes}
        with np.errstate(over="ignore", invalid="ignore"):
            out = np.asarray(spec.function(**kwargs), np.float32)
            if gain is not None:
                out = out * np.asarray(gain, np.float32)
            term = out if held is None else out - held
            term[..., list(mp.unchanged_channels)] = 0.0
            good = mask & _fin(out)
            image[good, :3] = rgb[good] + term[good]
        sss[good] = term[good]
    return image, sss, nonfinite


def _spoil(arrays: dict) -> dict:
    """Copies of the passes with NaN, +-inf or a negative value in every pass, each on its own
    pixel of the large sphere (Material Index 2), some on the plane and in the alpha."""
    arrays = {k: v.copy() for k, v in arrays.items()}
    skin = [tuple(p) for p in np.argwhere(arrays["Material Index"] == 2)]
    bad = iter(skin[3::7])
    for name in sorted(arrays):
        a = arrays[name]
        for value in (np.nan, np.inf, -np.inf, -0.5):
            pixel = next(bad)
            if a.ndim == 3:
                a[pixel + (len(pixel) % a.shape[2],)] = value
            else:
                a[pixel] = value
    plane = tuple(np.argwhere(arrays["Material Index"] == 1)[4])
    arrays["Combined"][plane] = (np.nan, -np.inf, 1.0, np.inf)
    arrays["Combined"][skin[1]][3] = np.nan  # alpha only: the pixel is computed, its alpha kept
    arrays["Combined"][skin[2]][:3] = -0.0
    return arrays


@pytest.mark.parametrize("technique", list(TECHNIQUES))
def test_apply_equals_the_long_way_with_nan_and_inf_in_every_pass(technique):
    clean, scene = sphere_scene(64, 40)
    arrays = _spoil(clean)
    kept = {k: v.copy() for k, v in arrays.items()}
    passes = Passes(arrays)
    p = plan(passes, scene, technique)
    assert p.applied  # something is computed, so the comparison means something
    with np.errstate(invalid="ignore"):
        image, sss, nonfinite = _reference(passes, scene, technique)
        out = apply(passes, scene, technique, prepared=p)
    assert nonfinite > 0 and p.nonfinite_pixels == nonfinite
    got_image, got_sss = out[f"SSSLab.{technique}.Image"], out[f"SSSLab.{technique}.SSS"]
    assert got_image.dtype == np.float32 and got_sss.dtype == np.float32
    np.testing.assert_array_equal(got_image.view(np.uint32), image.view(np.uint32))
    np.testing.assert_array_equal(got_sss.view(np.uint32), sss.view(np.uint32))
    assert (got_sss != 0).any()
    # Neither the caller's arrays nor the passes changed.
    for name, a in kept.items():
        np.testing.assert_array_equal(arrays[name].view(np.uint32), a.view(np.uint32))
        np.testing.assert_array_equal(passes[name].view(np.uint32), a.view(np.uint32))
    # The same on the clean passes, planned inside apply (which reuses the plan's index map).
    passes = Passes(clean)
    image, sss, nonfinite = _reference(passes, scene, technique)
    out = apply(passes, scene, technique)
    assert nonfinite == 0
    np.testing.assert_array_equal(out[f"SSSLab.{technique}.Image"].view(np.uint32), image.view(np.uint32))
    np.testing.assert_array_equal(out[f"SSSLab.{technique}.SSS"].view(np.uint32), sss.view(np.uint32))
