"""A technique that exists only in this test: registered in a registry of its own, it runs through
plan, apply and a comparison sweep without an edit anywhere else (``docs/adding-a-technique.md``)."""

from dataclasses import replace

import numpy as np
import pytest

from sss_lab.core.pipeline.apply import apply, layer_names
from sss_lab.core.pipeline.plan import plan
from sss_lab.core.scene.exr import Passes
from sss_lab.core.study import sweep
from sss_lab.core.study.synthetic import DEFAULT_MATERIALS, sphere_scene
from sss_lab.core.techniques.registry import TECHNIQUES, Registry, get_spec
from sss_lab.core.techniques.spec import Param, Technique


def dim(*, diffuse, albedo, mask, strength: float = 0.5) -> np.ndarray:
    """A stand-in that 'scatters' by keeping 1 - strength of the diffuse light on the mask."""
    out = (albedo * diffuse).astype(np.float32)
    out[mask] *= np.float32(1.0 - strength)
    return out


DIM = Technique(
    name="dim",
    label="Dim",
    description="Keeps part of the diffuse light (a test stand-in)",
    citation="tests/core/test_registry.py",
    function=dim,
    scatters=True,
    adds_light=False,
    passes=("Combined", "Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Depth", "Material Index"),
    params=(Param("strength", "Strength", "Share of the diffuse light taken away", min=0.0, max=1.0),),
    qualities=({"strength": 0.25}, {"strength": 0.5}),
    default_quality=1,
)


@pytest.fixture(scope="module")
def scene():
    arrays, desc = sphere_scene(24, 16)
    return arrays, Passes(arrays), desc


def test_a_registry_of_its_own():
    registry = Registry([DIM])
    assert list(registry) == ["dim"] and registry.get_spec("dim") is DIM
    assert "dim" not in TECHNIQUES
    with pytest.raises(ValueError, match="unknown technique 'sta'; expected one of: dim"):
        registry.get_spec("sta")
    with pytest.raises(TypeError, match="registered already"):
        registry.register(DIM)
    assert DIM.defaults == {"strength": 0.5}  # from the signature


def test_plan_and_apply_run_it(scene):
    arrays, passes, desc = scene
    technique = Registry([DIM]).get_spec("dim")
    p = plan(passes, desc, technique, strength=0.25)
    applied = {m.material.index for m in p.applied}
    assert applied == {m.index for m in DEFAULT_MATERIALS if m.scatters}
    assert all(m.params["strength"] == 0.25 for m in p.applied)
    assert "Dim (dim)" in p.explain()

    layers = apply(passes, desc, technique, prepared=p)
    image, sss = (layers[n] for n in layer_names("dim"))
    albedo = arrays["Diffuse Color"]
    diffuse = arrays["Diffuse Direct"] + arrays["Diffuse Indirect"]
    index = np.rint(arrays["Material Index"]).astype(int)
    on = np.isin(index, list(applied))
    # The SSS term is the light taken away: -strength x albedo x diffuse on the materials, 0 elsewhere.
    np.testing.assert_allclose(sss[on], -0.25 * (albedo * diffuse)[on], rtol=1e-5, atol=1e-7)
    assert not sss[~on].any()
    np.testing.assert_array_equal(image[~on], arrays["Combined"][~on])


def test_a_comparison_sweep_runs_its_quality_ladder(scene):
    _, passes, desc = scene
    reference = np.array(passes["Combined"], dtype=np.float32)
    mask = np.isin(np.rint(passes["Material Index"]).astype(int), [m.index for m in desc.materials if m.scatters])
    variants = [(DIM.quality_label(q), dict(q)) for q in DIM.qualities]
    rows = sweep.sweep(passes, desc, reference, mask, 2, DIM, "any", variants)
    assert [r["mapping"] for r in rows] == ["Dim strength=0.25", "Dim strength=0.5"]
    errors = [r["rel_rmse"] for r in rows]
    assert 0 < errors[0] < errors[1]  # taking less light away stays closer to the passes' own image
    assert rows[0].get("chosen") and not rows[1].get("chosen")


def test_a_grid_calibration_sweeps_its_parameters(scene):
    _, passes, desc = scene
    reference = np.array(passes["Combined"], dtype=np.float32)
    mask = np.ones(passes.shape, bool)
    calibrated = replace(DIM, calibration={"strength": (0.0, 0.5, 1.0)})
    rows = sweep.calibrate(passes, desc, reference, mask, box=2, techniques=[calibrated])["rows"]
    assert [r["mapping"] for r in rows] == ["strength=0", "strength=0.5", "strength=1"]
    assert rows[0]["rel_rmse"] == pytest.approx(0.0, abs=1e-6) and rows[0]["chosen"]


def test_what_calibrate_fits_is_the_specs_fit(monkeypatch):
    from sss_lab.core.pipeline import fit_params

    assert fit_params.FIT_PARAMETERS == {t.name: t.fit for t in TECHNIQUES.values() if t.fit}
    # A technique without a fit is not offered to calibrate; one with a fit is, without an edit elsewhere.
    monkeypatch.setattr(fit_params, "TECHNIQUES", Registry([DIM, replace(DIM, name="dim2", fit=("gain",))]))
    assert fit_params._fit_parameters() == {"dim2": ("gain",)}
    monkeypatch.setattr(fit_params, "TECHNIQUES", Registry([replace(DIM, fit=("radius",))]))
    with pytest.raises(TypeError, match=r"technique 'dim': fit names \['radius'\], which are not in"):
        fit_params._fit_parameters()
    with pytest.raises(TypeError, match="fit must be a tuple of parameter names"):
        replace(DIM, fit="gain")
    with pytest.raises(TypeError, match="names a parameter twice"):
        replace(DIM, fit=("gain", "gain"))


def test_samples_per_pixel_counts_samples_or_taps_and_one_per_light_added():
    """The machine-independent cost the report plots and ``auto`` weighs: the quality's samples or
    taps (defaults where the quality leaves them), plus one per light for light added from behind."""
    sta, ssss, burley, combined = (get_spec(n) for n in ("sta", "ssss", "burley", "combined"))
    assert sta.samples_per_pixel({}, lights=2) == 2 and sta.samples_per_pixel({}, lights=0) == 1
    assert ssss.samples_per_pixel({}, lights=3) == ssss.defaults["n_taps"] == 17
    assert ssss.samples_per_pixel({"n_taps": 11}, lights=3) == 11
    assert burley.samples_per_pixel({"n_samples": 8}, lights=5) == 8
    assert combined.samples_per_pixel({"n_samples": 16}, lights=2) == 18
    assert combined.samples_per_pixel({"diffusion": "ssss", "n_taps": 11}, lights=1) == 12
