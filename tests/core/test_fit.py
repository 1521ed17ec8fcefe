"""core/study/fit.py: recovering known parameters from a synthetic "Cycles" image made with them,
with and without Monte Carlo-like noise; the held-out check; the bad inputs.

The synthetic scene is core/study/synthetic.py's plane and spheres (the Skin sphere, pass index 2,
covers about 1900 pixels at 96 x 64). The reference is SSS Lab's own apply with the true fit,
so the model can represent it exactly: a noise-free fit must find the true values on the grid.
"""

import dataclasses
import re

import numpy as np
import pytest

from sss_lab.core.pipeline import apply as core_apply
from sss_lab.core.pipeline.mapping import burley_d, technique_params
from sss_lab.core.scene.exr import Passes
from sss_lab.core.scene.scene import SceneDescription
from sss_lab.core.study import fit as fit_mod
from sss_lab.core.study.fit import FitError, block_folds, fit_material, fit_scene, with_fits
from sss_lab.core.study.synthetic import sphere_scene
from sss_lab.core.techniques.burley.technique import sample_counts
from sss_lab.core.techniques.registry import get_spec

TRUTH = {
    "burley": {"gain": (1.2, 0.9, 0.8), "d_scale": 2**-0.5},
    "combined": {"gain": (1.2, 0.9, 0.8), "d_scale": 2**0.5, "transmission_scale": 0.5},
}


@pytest.fixture(scope="module")
def synthetic():
    arrays, scene = sphere_scene(96, 64)
    mats = tuple(dataclasses.replace(m, thickness_distance=0.5) if m.scatters else m for m in scene.materials)
    return Passes(arrays), dataclasses.replace(scene, materials=mats)


def _reference(passes, scene, technique, fit):
    materials = tuple(dataclasses.replace(m, fit={technique: fit}) if m.scatters else m for m in scene.materials)
    true = dataclasses.replace(scene, materials=materials)
    return core_apply.apply(passes, true, technique)[core_apply.layer_names(technique)[0]]


def _skin(scene):
    return scene.material(2)


@pytest.mark.parametrize("technique", ["burley", "combined"])
def test_noise_free_fit_finds_the_true_values(synthetic, technique):
    passes, scene = synthetic
    ref = _reference(passes, scene, technique, TRUTH[technique])
    r = fit_material(passes, scene, ref, _skin(scene), technique, regularization=0.0)
    # The true d_scale is on the search grid, the gains and scale are solved in closed form:
    # float32 rendering of the reference is the only error left.
    assert r.params["d_scale"] == pytest.approx(TRUTH[technique]["d_scale"], rel=1e-9)
    np.testing.assert_allclose(r.params["gain"], TRUTH[technique]["gain"], rtol=1e-3)
    if technique == "combined":
        assert "transmission_d_su" in r.params  # the back light reaches the sphere's thin rim
    assert r.heldout_after < 0.01 * r.heldout_before
    assert r.params["info"]["heldout_after"] == r.heldout_after


def test_sta_scale_is_found_and_its_provenance_counts_pixels(synthetic):
    passes, scene = synthetic
    ref = _reference(passes, scene, "sta", {"scale": 2.0})
    r = fit_material(passes, scene, ref, _skin(scene), "sta", regularization=0.0, samples=32)
    # Solved in closed form: float32 rendering of the reference is the only error left.
    assert r.params["scale"] == pytest.approx(2.0, rel=1e-6)
    assert r.heldout_after < 1e-3 * r.heldout_before
    # The provenance's pixels are the material's, as for the other techniques (not its blocks).
    skin = int(np.count_nonzero(core_apply.index_map(passes) == 2))
    assert r.params["info"] == {**r.params["info"], "samples": 32, "pixels": skin}
    assert r.blocks == r.heldout_blocks < skin


def test_the_fitted_transmission_scale_stays_within_its_bound(synthetic):
    """A reference with 8 x the light from behind: the fit keeps its scale at the fit's bound, 4
    (the gains' factor), and says so; a scale of 8 set by hand (or stored by an earlier fit,
    within the parameters' bounds) is still accepted and used."""
    passes, scene = synthetic
    truth = {**TRUTH["combined"], "transmission_scale": 8.0}
    ref = _reference(passes, scene, "combined", truth)
    r = fit_material(passes, scene, ref, _skin(scene), "combined", regularization=0.0)
    assert max(r.params["transmission_scale"]) == fit_mod.TRANSMISSION_SCALE_MAX == 4.0
    assert "transmission_scale" in r.at_bounds
    # The light from behind it cannot reach leaves an error the true values do not.
    assert r.train_after > 1e-3 * r.train_before
    by_hand = dataclasses.replace(_skin(scene), fit={"combined": truth})
    assert by_hand.fit["combined"]["transmission_scale"] == (8.0, 8.0, 8.0)


@pytest.mark.parametrize("technique", ["burley", "combined"])
def test_the_adaptive_plan_does_not_move_with_the_d_the_fit_tries(synthetic, technique):
    """Burley's adaptive counts (the default) are planned from the material's own d for every k the
    fit tries, and apply gives a fitted material that plan: the counts do not step as k moves
    (they would, planned from each k's d), and the model stays apply's (the noise-free tests)."""
    passes, scene = synthetic
    skin = _skin(scene)
    single = dataclasses.replace(scene, materials=(skin,))
    diffusion = fit_mod._Diffusion(passes, single, get_spec(technique), np.ones((32, 48), bool), 2)
    kw = diffusion.kwargs
    own = burley_d(skin)
    assert kw["adaptive"] is True and kw["plan_d_su"] == own
    planned = sample_counts(**{**kw, "d_su": own})
    assert planned.max() == 32 and 0 < planned[planned > 0].min() < 32  # the plan varies on the sphere
    moved = 0
    for k in fit_mod.GRID:
        d = tuple(diffusion.d0 * k)
        np.testing.assert_array_equal(sample_counts(**{**kw, "d_su": d}), planned)
        moved += not np.array_equal(sample_counts(**{**kw, "d_su": d, "plan_d_su": None}), planned)
    assert moved == len(fit_mod.GRID) - 1  # every k but 1 would move them, planned from its own d
    # apply's parameters for a fitted material: the fitted d, the plan of the material's own.
    fitted = dataclasses.replace(skin, fit={technique: {"gain": (1.0, 1.0, 1.0), "d_scale": 2.0}})
    params = technique_params(fitted, technique)
    assert params["plan_d_su"] == own and params["d_su"] == tuple(v * 2.0 for v in own)
    assert "plan_d_su" not in technique_params(skin, technique)  # unfitted: the plan of d_su itself
    assert "plan_d_su" not in technique_params(dataclasses.replace(skin, fit={"ssss": {"d_scale": 2.0}}), "ssss")


@pytest.mark.parametrize("technique", ["burley", "ssss"])
def test_a_fit_without_normal_and_position_passes_finds_the_true_values(synthetic, technique):
    """Without the Normal and Position passes the energy stage of a random-walk material
    renormalizes each channel's total over the material (core/optics/energy.py, "view"): not affine in
    the light, so the fit runs it on every k's light instead of its affine form; the result must
    still be what apply gives."""
    passes, scene = synthetic
    bare = Passes({n: passes[n] for n in passes if n not in ("Normal", "Position")})
    walk = dataclasses.replace(_skin(scene), method="RANDOM_WALK")
    scene = dataclasses.replace(scene, materials=tuple(walk if m.index == 2 else m for m in scene.materials))
    single = dataclasses.replace(scene, materials=(walk,))
    keep = np.ones((16, 24), bool)
    assert not fit_mod._Diffusion(bare, single, get_spec(technique), keep, 4).affine
    assert fit_mod._Diffusion(passes, single, get_spec(technique), keep, 4).affine
    truth = TRUTH["burley"]
    ref = _reference(bare, scene, technique, truth)
    r = fit_material(bare, scene, ref, walk, technique, regularization=0.0)
    # As in the noise-free test above: k on the grid, g in closed form, float32 rounding left.
    assert r.params["d_scale"] == pytest.approx(truth["d_scale"], rel=1e-9)
    np.testing.assert_allclose(r.params["gain"], truth["gain"], rtol=1e-3)


@pytest.mark.parametrize("box", [2, 4])
def test_noisy_fit_is_close_and_holds(synthetic, box):
    passes, scene = synthetic
    ref = _reference(passes, scene, "burley", TRUTH["burley"])
    rng = np.random.default_rng(7)
    noisy = ref.copy()
    # 30 % multiplicative per-pixel noise: about what 16-32 samples of random walk leave.
    noisy[..., :3] *= (1.0 + 0.3 * rng.standard_normal(ref[..., :3].shape)).astype(np.float32)
    r = fit_material(passes, scene, noisy, _skin(scene), "burley", box=box)
    # Tolerance: the ridge pulls g towards 1 by lam |g - 1| / (1 + lam) <= 0.05 x 0.2 / 1.05 = 0.0095,
    # and the block means' noise (0.3 / box per block; ~70 blocks of 4 x 4, ~280 of 2 x 2: the
    # same noise on the gain, 0.3 / sqrt(pixels)) adds about 0.01.
    np.testing.assert_allclose(r.params["gain"], TRUTH["burley"]["gain"], atol=0.03)
    if box == 4:
        # 4 x 4 block means keep 0.3 / 4 = 7.5 % of noise: less than half of the held-out error
        # before the fit (the default's own error is about 20 %); 2 x 2 keep 15 %, about as much.
        assert r.heldout_after < 0.5 * r.heldout_before


def _fold_pixels(passes, material):
    """{fold: its blocks' pixels} as ``fit_material`` deals the blocks of ``material`` (defaults)."""
    box = fit_mod.BOX
    mask = core_apply.index_map(passes) == material.index
    keep = fit_mod.box_downsample(mask.astype(float), box) >= 1.0
    fold = block_folds(int(keep.sum()), folds=fit_mod.FOLDS, seed=0)
    out = {}
    for j in range(fit_mod.FOLDS):
        blocks = np.zeros(keep.shape, bool)
        blocks[keep] = fold == j
        out[j] = np.kron(blocks, np.ones((box, box), bool))
    return out


def test_every_block_is_held_out_once():
    fold = block_folds(103, folds=4, seed=0)
    sizes = np.bincount(fold, minlength=4)
    assert sizes.sum() == 103 and sizes.max() - sizes.min() <= 1 and len(sizes) == 4
    np.testing.assert_array_equal(fold, block_folds(103, folds=4, seed=0))  # a fixed seed, the same folds
    assert np.any(fold != block_folds(103, folds=4, seed=1))
    # Dealt at random, not in row-major stripes.
    assert not np.array_equal(fold, np.arange(103) % 4)


def test_a_fit_that_does_not_hold_is_rejected(synthetic):
    """Two folds say "1.2 x as bright", the two others "0.8 x": every block is 1.2 or 0.8 x the
    unfitted light (error 0.2 of it), and each fold's fit on the other three (gain about
    (1.2 + 0.8 + 0.8) / 3 = 0.93 for a bright fold) misses its blocks by more (0.27): rejected,
    with one line naming the material."""
    passes, scene = synthetic
    skin = _skin(scene)
    default = _reference(passes, scene, "burley", {})
    ref = default.copy()
    folds = _fold_pixels(passes, skin)
    for j, factor in enumerate((1.2, 1.2, 0.8, 0.8)):
        ref[folds[j], :3] *= factor
    with pytest.raises(FitError, match="'Skin' burley: the fit does not hold on the held-out pixels"):
        fit_material(passes, scene, ref, skin, "burley")
    # With the check off (benchmarks.fit --keep-refused) the same fit is kept, and says so, with
    # the values fitted on every block: a gain near the blocks' mean factor, 1 (the folds' shares
    # of the light differ by a few per cent; the ridge pulls towards 1 as well).
    kept = fit_material(passes, scene, ref, skin, "burley", heldout_check=False)
    assert kept.heldout_after >= kept.heldout_before
    np.testing.assert_allclose(kept.params["gain"], 1.0, atol=0.03)
    assert any("held-out check off" in n for n in kept.notes)
    with pytest.raises(FitError, match="folds: expected a whole number from 2 to 16, got 1"):
        fit_material(passes, scene, ref, skin, "burley", folds=1)


def test_a_fit_that_holds_keeps_the_values_fitted_on_every_block(synthetic):
    """Three folds say "1.2 x as bright", one "1.3 x": the held-out error is each fold predicted
    by the fit on the other three, and the values kept are fitted on every block."""
    passes, scene = synthetic
    skin = _skin(scene)
    default = _reference(passes, scene, "burley", {})
    ref = default.copy()
    ref[..., :3] *= 1.2
    ref[_fold_pixels(passes, skin)[0], :3] *= 1.3 / 1.2
    r = fit_material(passes, scene, ref, skin, "burley", regularization=0.0)
    # On every block: about sum(S y) / sum(S^2), a mean of 1.3 (a quarter of the light) and 1.2,
    # 1.225 (the folds' shares of sum(S^2) differ by a few per cent; k may move a little).
    g = np.asarray(r.params["gain"])
    assert np.all(g > 1.21) and np.all(g < 1.24)
    # Held out, with equal folds of light a: fold 0 predicted by 1.2 (off by 0.1), each other fold
    # by (1.3 + 2 x 1.2) / 3 (off by 0.1 / 3): 0.01 a + 3 x 0.0011 a, against the unfitted
    # 0.09 a + 3 x 0.04 a; the ratio of the RMSEs sqrt(0.0133 / 0.21) = 0.252 (10 %: the folds'
    # shares of the light and k).
    assert r.heldout_after / r.heldout_before == pytest.approx(0.252, rel=0.1)
    assert r.heldout_blocks == r.blocks and r.folds == 4


def _small_wax(passes, scene, rows=6):
    """The passes with only ``rows`` rows of the Wax sphere (pass index 3) left as Wax: fewer than
    32 blocks even of 2 x 2."""
    index = np.array(passes["Material Index"])
    wax = np.rint(index) == 3
    ys = np.nonzero(wax.any(axis=1))[0]
    index[wax & (np.arange(index.shape[0])[:, None] >= ys[0] + rows)] = 0.0
    return Passes({**{n: passes[n] for n in passes}, "Material Index": index})


def test_a_small_material_is_fitted_on_smaller_blocks(synthetic):
    passes, scene = synthetic
    wax = scene.material(3)  # about 460 pixels: 19 blocks of 4 x 4, about 100 of 2 x 2
    ref = _reference(passes, scene, "burley", TRUTH["burley"])
    r = fit_material(passes, scene, ref, wax, "burley", regularization=0.0)
    assert r.blocks + r.heldout_blocks > 4 * 19
    assert r.params["d_scale"] == pytest.approx(TRUTH["burley"]["d_scale"], rel=1e-9)


def test_bad_inputs_give_one_clear_line(synthetic):
    passes, scene = synthetic
    ref = passes["Combined"]
    small = _small_wax(passes, scene)
    wax = scene.material(3)
    with pytest.raises(FitError, match=r"material 'Wax' covers \d+ pixels.*of 2x2\): too few to fit.*left unchanged"):
        fit_material(small, scene, ref, wax, "burley")
    plain = dataclasses.replace(
        scene, materials=tuple(dataclasses.replace(m, subsurface_weight=0.0) for m in scene.materials)
    )
    with pytest.raises(FitError, match="no material in the scene scatters light"):
        fit_scene(passes, plain, ref)
    no_bake = dataclasses.replace(_skin(scene), thickness_distance=0.0)
    with pytest.raises(FitError, match="'Skin': its thickness map has no bake distance"):
        fit_material(passes, scene, ref, no_bake, "combined")
    with pytest.raises(FitError, match="reference: expected an image of the passes' size 96x64"):
        fit_material(passes, scene, ref[:10], _skin(scene), "burley")
    # fit_scene reports the material it could not fit and fits the others.
    results, problems = fit_scene(small, scene, _reference(passes, scene, "burley", TRUTH["burley"]))
    assert [r.material for r in results] == ["Skin"] and len(problems) == 1 and "'Wax'" in problems[0]


def test_the_fit_travels_in_the_scene_description_and_apply_uses_it(synthetic):
    passes, scene = synthetic
    ref = _reference(passes, scene, "burley", TRUTH["burley"])
    results, _ = fit_scene(_small_wax(passes, scene), scene, ref, techniques=("burley",), regularization=0.0)
    fitted = with_fits(scene, results)  # the Wax too small to fit: no fit
    again = SceneDescription.from_json(fitted.to_json())
    assert again.material(2).fit["burley"]["d_scale"] == pytest.approx(2**-0.5)
    assert again.material(3).fit == {}
    out = core_apply.apply(passes, again, "burley")["SSSLab.burley.Image"]
    skin = core_apply.index_map(passes) == 2
    np.testing.assert_allclose(out[skin], ref[skin], rtol=2e-3, atol=1e-5)
    text = core_apply.plan(passes, again, "burley").explain()
    found = re.search(r"fitted to Cycles: d_scale=0\.7071, gain=\(([\d.]+), ([\d.]+), ([\d.]+)\)", text)
    # The gains as printed (4 digits), within the noise-free fit's float32 tolerance above (1e-3).
    assert found and "held-out error" in text
    np.testing.assert_allclose([float(v) for v in found.groups()], TRUTH["burley"]["gain"], rtol=1e-3)
    # Hand-edited values outside the bounds, or unknown names, are rejected with the bounds.
    with pytest.raises(ValueError, match="fitted gain: .* is outside 0.25..4"):
        dataclasses.replace(scene.material(2), fit={"burley": {"gain": (5.0, 1.0, 1.0)}})
    # One number for a per-channel value is read for the three channels, and named as written.
    with pytest.raises(ValueError, match=r"fitted gain: 9\.0 is outside 0.25..4"):
        dataclasses.replace(scene.material(2), fit={"burley": {"gain": 9.0}})
    with pytest.raises(ValueError, match="unknown parameter 'radius'"):
        dataclasses.replace(scene.material(2), fit={"burley": {"radius": 1.0}})


def test_a_refused_fit_is_collected_and_only_the_pairs_asked_for_are_fitted(synthetic):
    """``fit_scene``'s ``refused`` gets each fit the held-out check refused, with its problem
    line (``calibrate`` renders more samples for those); ``only`` fits the pairs named and skips
    every other material and technique."""
    passes, scene = synthetic
    skin = _skin(scene)
    ref = _reference(passes, scene, "burley", {})
    folds = _fold_pixels(passes, skin)
    for j, factor in enumerate((1.2, 1.2, 0.8, 0.8)):  # as in the test of a fit that does not hold
        ref[folds[j], :3] *= factor
    refused: list = []
    results, problems = fit_scene(
        passes, scene, ref, techniques=("burley",), only={("Skin", "burley")}, refused=refused, samples=32
    )
    assert results == []
    assert len(refused) == 1 and refused[0][:2] == ("Skin", "burley")
    assert problems == [refused[0][2]]
    assert "does not hold on the held-out pixels" in problems[0] and "32 samples" in problems[0]
    # Without ``only`` the other scattering materials are fitted (or named) as well.
    others, missed = fit_scene(passes, scene, ref, techniques=("burley",))
    assert {r.material for r in others} | {p.split("'")[1] for p in missed} == {
        m.name for m in scene.materials if m.scatters
    }
    assert len([m for m in scene.materials if m.scatters]) > 1


def test_the_render_time_is_split_into_a_fixed_part_and_one_per_sample():
    """Two renders of one view, 32 samples in 2.0 s and 1 in 0.45 s: 0.05 s per sample and 0.4 s
    fixed (exact in binary up to rounding). Pairs that tell nothing give None."""
    fixed, per = fit_mod.render_time_split(2.0, 32, 0.45)
    assert per == pytest.approx(0.05, rel=1e-12) and fixed == pytest.approx(0.4, rel=1e-12)
    assert fit_mod.render_time_split(2.0, 32, 2.5) is None  # the pilot slower: no time per sample
    assert fit_mod.render_time_split(2.0, 32, 0.45, pilot_samples=32) is None
    assert fit_mod.render_time_split(float("nan"), 32, 0.45) is None
    assert fit_mod.render_time_split(2.0, True, 0.45) is None
    # A fixed part the pilot cannot account for is 0, not negative.
    assert fit_mod.render_time_split(3.1, 32, 0.05)[0] == 0.0


def test_more_samples_stays_within_the_budget():
    """The estimate of ``more_samples``: a converged render of 1024 samples takes 0.4 + 1024 x 0.05
    = 51.6 s; spent so far 3.95 s; 32 more samples 0.4 + 1.6 s and a second fit of 0.5 s: 6.45 s in
    all, 12.5 % of it. Within a budget of 15 %, 32 more samples; within 9 %, none, and the line
    says what it would have cost (numbers exact up to rounding, checked to the printed digit)."""
    times = dict(spent_s=3.95, render_s=2.0, pilot_s=0.45, fit_s=0.5)
    extra, why = fit_mod.more_samples(samples=32, max_samples=64, budget=0.15, **times)
    assert extra == 32 and "12.5% of a 1024-sample render" in why and "51.6 s" in why
    extra, why = fit_mod.more_samples(samples=32, max_samples=64, budget=0.09, **times)
    assert extra == 0 and why.startswith("32 more samples would cost 12.5%")
    # The same times for a 16-sample render: 0.1033 s per sample, 0.3467 s fixed, a converged
    # render of 106.2 s; 48 more samples bring the total to 9.76 s, 9.2 % of it.
    extra, why = fit_mod.more_samples(samples=16, max_samples=64, budget=0.10, **times)
    assert extra == 48 and "9.2% of a 1024-sample render" in why
    assert fit_mod.more_samples(samples=16, max_samples=64, budget=0.09, **times)[0] == 0
    assert fit_mod.more_samples(samples=64, max_samples=64, **times) == (0, "64 samples already (at most 64)")
    extra, why = fit_mod.more_samples(samples=32, max_samples=64, **{**times, "pilot_s": 2.0})
    assert extra == 0 and "no estimate" in why


def test_the_second_fits_inputs_and_lines():
    # The mean of two renders by their sample counts, in the first's dtype; the refusals replaced.
    first = np.full((2, 2, 4), 1.0, np.float32)
    second = np.full((2, 2, 4), 4.0, np.float32)
    mean = fit_mod.mean_render(first, 32, second, 96)
    assert mean.dtype == np.float32
    np.testing.assert_array_equal(mean, np.full((2, 2, 4), 0.25 * 1.0 + 0.75 * 4.0, np.float32))
    refused = [("Jade", "burley", "refused burley"), ("Jade", "combined", "refused combined")]
    assert fit_mod.refused_pairs(refused) == {("Jade", "burley"), ("Jade", "combined")}
    lines = ["too few pixels", "refused burley", "refused combined"]
    assert fit_mod.after_second_fit(lines, refused, ["refused combined again"]) == [
        "too few pixels",
        "refused combined again",
    ]


def test_a_fit_a_technique_does_not_make_is_refused_where_it_is_read():
    # The scene description checks a fit's values against the bounds (core.scene.fit_values); which
    # technique fits which parameters is the registry's, checked where a technique's fit is read.
    from sss_lab.core.pipeline.fit_params import fitted

    assert fitted({"burley": {"gain": (1.0, 2.0, 1.5), "info": {"samples": 4}}}, "burley") == {"gain": (1.0, 2.0, 1.5)}
    with pytest.raises(ValueError, match="unknown parameter 'scale'"):
        fitted({"burley": {"scale": 2.0}}, "burley")
    with pytest.raises(ValueError, match="unknown technique 'nope'"):
        fitted({"nope": {"gain": 1.0}}, "burley")


@pytest.mark.parametrize("technique", ["burley", "combined", "sta"])
def test_a_weight_below_one_is_undone_before_the_fit(synthetic, technique):
    """Apply mixes the technique's light by the Subsurface Weight (Cycles' (1 - w) diffuse + w
    subsurface); the fit matches the technique's own light, so on a reference made at weight 0.5
    it finds the true values as at weight 1. Without undoing the mix it could not: the gain would
    absorb half of the change."""
    passes, scene = synthetic
    half = dataclasses.replace(
        scene,
        materials=tuple(dataclasses.replace(m, subsurface_weight=0.5) if m.scatters else m for m in scene.materials),
    )
    truth = TRUTH.get(technique, {"scale": 2.0})
    ref = _reference(passes, half, technique, truth)
    r = fit_material(passes, half, ref, _skin(half), technique, regularization=0.0)
    if technique == "sta":
        assert r.params["scale"] == pytest.approx(2.0, rel=1e-5)
    else:
        assert r.params["d_scale"] == pytest.approx(truth["d_scale"], rel=1e-9)
        np.testing.assert_allclose(r.params["gain"], truth["gain"], rtol=1e-3)
    assert r.heldout_after < 0.01 * r.heldout_before


def test_a_technique_worse_than_no_sss_even_fitted_is_switched_off(synthetic):
    """A "Cycles" image that is the passes' own Combined, with the diffuse light modulated pixel by
    pixel (a checkerboard no blur keeps): no SSS is exact there, and Burley, whatever its fit, blurs
    the pattern away. The fit stores ``off`` with the errors, the plan leaves the material as it is
    and says why, and apply keeps Combined there to the bit; Clear Fit (an empty fit) uses it again."""
    passes, scene = synthetic
    arrays = {n: np.array(passes[n]) for n in passes.names}
    rows, cols = np.indices(arrays["Depth"].shape)
    checker = np.where((rows + cols) % 2 == 0, 1.6, 0.4).astype(np.float32)[..., None]
    original = arrays["Diffuse Color"] * (arrays["Diffuse Direct"] + arrays["Diffuse Indirect"])
    arrays["Diffuse Direct"] = arrays["Diffuse Direct"] * checker
    arrays["Combined"][..., :3] += arrays["Diffuse Color"] * (arrays["Diffuse Direct"] + arrays["Diffuse Indirect"])
    arrays["Combined"][..., :3] -= original
    checkered = Passes(arrays)
    ref = np.array(arrays["Combined"])
    r = fit_material(checkered, scene, ref, _skin(scene), "burley")
    assert r.params["off"] == 1.0 and set(r.params) == {"off", "info"}
    assert r.heldout_after >= r.heldout_none and r.params["info"]["heldout_none"] == r.heldout_none
    assert any("worse than no SSS" in n for n in r.notes)
    off = with_fits(scene, [r])
    again = SceneDescription.from_json(off.to_json())
    p = core_apply.plan(checkered, again, "burley")
    skin = next(mp for mp in p.materials if mp.material.index == 2)
    assert skin.skip is not None and "worse than no SSS" in skin.skip and "Clear Fit" in skin.skip
    out = core_apply.apply(checkered, again, "burley")["SSSLab.burley.Image"]
    mask = core_apply.index_map(checkered) == 2
    np.testing.assert_array_equal(out[mask], ref[mask])
    cleared = dataclasses.replace(again.material(2), fit={})
    assert core_apply.plan(checkered, dataclasses.replace(again, materials=(cleared,)), "burley").applied


def test_auto_does_not_pick_a_technique_calibrate_switched_off(synthetic):
    """A material whose Burley fit is ``off``: Burley is not a candidate of ``auto`` there, and says
    why; the other techniques still are."""
    from sss_lab.core.pipeline.auto import choose

    passes, scene = synthetic
    info = {"samples": 32, "heldout_before": 0.2, "heldout_after": 0.2, "heldout_none": 0.1, "pixels": 100}
    skin = dataclasses.replace(_skin(scene), fit={"burley": {"off": 1.0, "info": info}})
    off = dataclasses.replace(scene, materials=tuple(skin if m.index == 2 else m for m in scene.materials))
    auto = choose(passes, off)
    choice = next(c for c in auto.choices if c.material.index == 2)
    burley = [c for c in choice.candidates if c.technique == "burley"]
    assert burley and all("worse than no SSS" in (c.excluded or "") for c in burley)
    assert not choice.chosen.startswith("burley")
    assert any(c.excluded is None for c in choice.candidates if c.technique not in ("burley", "none"))
