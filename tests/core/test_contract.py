"""The contract between a technique's spec and the layers that read it (no Blender).

Every registered technique (``core.techniques.registry.TECHNIQUES``): its parameters are keyword-only
arguments of its function with their defaults from the signature, every run of its quality
ladder is accepted by plan and apply, every pass it reads is in the pass table, and the
material mapping gives it only keywords it takes. The Blender layers (properties, panel rows,
compositor builders) are held to it in ``tests/blender/test_contract.py``; the recipe that
keeps a new technique in step is ``docs/adding-a-technique.md``.
"""

import inspect
from dataclasses import replace

import numpy as np
import pytest

from sss_lab.core.pipeline import mapping
from sss_lab.core.pipeline.apply import apply, layer_names
from sss_lab.core.pipeline.call import call_technique
from sss_lab.core.pipeline.plan import plan
from sss_lab.core.scene.exr import Passes
from sss_lab.core.scene.passes import PASSES, THICKNESS
from sss_lab.core.study import fidelity
from sss_lab.core.study.synthetic import DEFAULT_MATERIALS, sphere_scene
from sss_lab.core.techniques.registry import TECHNIQUES, Registry, parse_params
from sss_lab.core.techniques.spec import CALIBRATE_MAPPING, Param, Technique

SPECS = list(TECHNIQUES.values())
IDS = list(TECHNIQUES)


@pytest.fixture(scope="module")
def scene():
    arrays, desc = sphere_scene(24, 16)
    # The sphere materials carry a bake distance, so that a technique reading the thickness map
    # as a slab (STA's Burley falloff, the combined technique) runs in full.
    materials = tuple(replace(m, thickness_distance=0.5) if m.scatters else m for m in DEFAULT_MATERIALS)
    desc = replace(desc, materials=materials)
    return Passes(arrays), desc


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_parameters_are_keywords_with_their_signature_defaults(spec):
    sig = inspect.signature(spec.function).parameters
    assert spec.params, f"{spec.name}: no parameter a user can set"
    for p in spec.params:
        assert sig[p.name].kind is inspect.Parameter.KEYWORD_ONLY
        assert p.default == sig[p.name].default
        assert p.label and p.description
        assert p.check(p.default) == p.default  # the default is inside its own range and choices


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_every_pass_is_in_the_pass_table(spec):
    for name in spec.passes:
        assert name == THICKNESS or name in PASSES, name
    assert {"Combined", "Material Index"} <= set(spec.passes)
    if spec.scatters:  # what apply reads for every scattering technique
        assert {"Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Depth"} <= set(spec.passes)


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_the_quality_ladder_is_valid_and_holds_the_defaults(spec):
    assert 0 <= spec.default_quality < len(spec.qualities)
    for quality in spec.qualities:
        assert set(quality) <= spec.keywords
        spec.check_params({k: v for k, v in quality.items() if k in spec.param_names})
    default = spec.qualities[spec.default_quality]
    assert all(spec.defaults[k] == v for k, v in default.items() if k in spec.defaults)
    labels = [spec.quality_label(q) for q in spec.qualities]
    assert len(set(labels)) == len(labels), labels  # compare names its runs by these


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_every_quality_runs_through_plan_and_apply(spec, scene):
    passes, desc = scene
    for quality in spec.qualities:
        p = plan(passes, desc, spec.name, **quality)
        assert p.applied, f"{spec.name} {quality}: no material planned"
        for mp in p.applied:
            footprint = spec.footprint(mp.params)
            assert (mp.kernel_su, mp.samples) == (footprint.radius_su, footprint.samples)
        layers = apply(passes, desc, spec.name, prepared=p)
        image, sss = (layers[n] for n in layer_names(spec.name))
        assert image.dtype == np.float32 and np.isfinite(image).all()
        assert np.abs(sss).max() > 0, f"{spec.name} {quality} changed nothing on the spheres"


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_the_mapping_gives_only_what_the_function_takes(spec):
    params = mapping.technique_params(DEFAULT_MATERIALS[1], spec.name)
    assert set(params) <= spec.keywords
    assert {k: params[k] for k in spec.defaults} == spec.defaults


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_calibration_sweeps_parameters_it_has(spec):
    if spec.calibration is None or spec.calibration == CALIBRATE_MAPPING:
        return
    for name, values in spec.calibration.items():
        for value in values:
            spec.param(name).check(value)


def test_bad_parameter_values_name_the_key_and_what_is_allowed():
    burley = TECHNIQUES["burley"]
    with pytest.raises(ValueError, match=r"burley.n_samples: expected an integer in \[1, 1024\], got 0"):
        burley.check_params({"n_samples": 0})
    with pytest.raises(ValueError, match=r"burley has no parameter 'taps'; its parameters: n_samples, random_rotation"):
        burley.check_params({"taps": 3})
    with pytest.raises(ValueError, match=r"ssss.n_taps: expected one of 11, 17, 25, got 12"):
        TECHNIQUES["ssss"].check_params({"n_taps": 12})
    assert TECHNIQUES["sta"].param("power").parse("3") == 3.0
    assert TECHNIQUES["burley"].param("random_rotation").parse("yes") is True


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_every_parameter_can_be_set_on_the_command_line(spec):
    """``apply --param`` parses each parameter's default back to the default, qualified or not."""
    for p in spec.params:
        text = str(p.default)
        assert parse_params([f"{p.name}={text}"], [spec.name]) == {spec.name: {p.name: p.default}}
        both = parse_params([f"{spec.name}.{p.name}={text}"], [spec.name, "burley" if spec.name != "burley" else "sta"])
        assert both[spec.name] == {p.name: p.default}


def keep(*, diffuse, albedo, mask, share: float = 0.5) -> np.ndarray:
    """A stand-in that takes neither ``depth`` nor ``camera``: keeps ``share`` of the light on the mask."""
    out = (albedo * diffuse).astype(np.float32)
    out[mask] *= np.float32(share)
    return out


KEEP = Technique(
    name="keep",
    label="Keep",
    description="Keeps part of the diffuse light (a test stand-in without depth or camera)",
    citation="tests/core/test_contract.py",
    function=keep,
    scatters=True,
    adds_light=False,
    passes=("Combined", "Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Depth", "Material Index"),
    params=(Param("share", "Share", "Share of the diffuse light kept", min=0.0, max=1.0),),
    qualities=({"share": 0.5},),
)


@pytest.mark.parametrize("spec", [*SPECS, Registry([KEEP]).get_spec("keep")], ids=[*IDS, "keep"])
def test_the_fidelity_table_measures_every_technique(spec):
    """Each technique is called with the inputs its function takes, whichever of the offered ones
    it leaves out (``call_technique``)."""
    material = DEFAULT_MATERIALS[1]
    row = fidelity.measure(spec, material)
    assert len(row["r90_su"]) == len(row["energy_ratio"]) == 3
    assert all(np.isfinite(row["energy_ratio"]))
    table = fidelity.fidelity_table(material, techniques=(spec,))
    assert set(table["rows"]) == {spec.label, "Burley profile (analytic)"}
    if spec is KEEP:
        assert row["r90_su"] == [0.0, 0.0, 0.0]  # local
        assert row["energy_ratio"] == pytest.approx([0.5] * 3)


def test_call_technique_passes_only_the_keywords_a_function_takes():
    got = call_technique(
        KEEP,
        diffuse=np.ones((1, 1, 3)),
        albedo=np.ones((1, 1, 3)),
        mask=np.ones((1, 1), bool),
        depth=None,
        camera=None,
        share=0.25,
    )
    assert got.tolist() == [[[0.25] * 3]]
    assert call_technique(lambda **kw: sorted(kw), a=1, b=2) == ["a", "b"]  # **kwargs takes them all
