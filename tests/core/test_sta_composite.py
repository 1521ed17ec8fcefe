"""STA's compiled route through ``core.pipeline.apply`` (``Technique.composite``: STA and the
compositing in one kernel per material, ``core.techniques.sta._kernels.sta_composite``) gives the
generic route's bits (``sta``, then ``core.pipeline._kernels.composite``) and its counts: the
same Image and SSS layers to the bit and the same pixels left for NaN/Inf inputs, overflowed and
clamped to no negative light. Bit equality: no tolerance anywhere. Both routes run on the
compiled backend here; in check mode (every other core test) ``apply`` compares them itself."""

from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest

from sss_lab.core.compute import backend
from sss_lab.core.pipeline import apply as core_apply
from sss_lab.core.pipeline.plan import plan
from sss_lab.core.scene.exr import Passes
from sss_lab.core.scene.scene import Light
from sss_lab.core.study.synthetic import LIGHTS, sphere_scene
from sss_lab.core.techniques import registry
from sss_lab.core.techniques.sta import technique as sta_technique

needs_numba = pytest.mark.skipif(backend.compiled() is None, reason="Numba cannot load")

STA = registry.get_spec("sta")
#: The same technique without its route: ``apply`` takes the generic one.
GENERIC = dataclasses.replace(STA, composite=None)


def test_a_spec_with_another_function_drops_the_route():
    """A route computes its technique's function: a spec made with another one (a stand-in)
    takes the generic route."""
    assert STA.composite is sta_technique.composite

    def stand_in(**kw):
        return STA.function(**kw)

    stand_in.__signature__ = inspect.signature(STA.function)
    assert dataclasses.replace(STA, function=stand_in).composite is None
    assert dataclasses.replace(STA, label="STA again").composite is sta_technique.composite


def _matrix(position, forward):
    """A row-major matrix_world at ``position`` whose local -Z points along ``forward``."""
    z = -np.asarray(forward, np.float64)
    z /= np.linalg.norm(z)
    helper = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, position
    return tuple(m.ravel())


BEHIND = ((0.2, 0.3, -8.0), (0.0, 0.0, 1.0))  # behind the spheres, facing the camera
LIGHT_SETS = {
    "suns": LIGHTS,
    "point, spot, area": (
        Light(type="POINT", name="P", energy=300.0, matrix_world=_matrix(*BEHIND)),
        Light(type="SPOT", name="S", energy=500.0, matrix_world=_matrix(*BEHIND), spot_size=1.2, spot_blend=0.3),
        Light(type="AREA", name="A", energy=200.0, matrix_world=_matrix(*BEHIND), size=0.5),
    ),
    "coloured and grey": (
        dataclasses.replace(LIGHTS[1], color=(1.0, 0.4, 0.2)),
        dataclasses.replace(LIGHTS[0], color=(0.5, 0.5, 0.5)),
    ),
    "no light": (dataclasses.replace(LIGHTS[1], energy=0.0),),
}


def _frame(w=72, h=40, rgb=False, weight=1.0):
    """The synthetic spheres (``sphere_scene``) with a bake distance, so that every falloff runs."""
    arrays, scene = sphere_scene(w, h)
    materials = tuple(
        dataclasses.replace(m, thickness_distance=0.4, subsurface_weight=weight) if m.scatters else m
        for m in scene.materials
    )
    scene = dataclasses.replace(scene, materials=materials)
    if rgb:
        arrays["Combined"] = np.ascontiguousarray(arrays["Combined"][..., :3])
    return arrays, scene


def _both(arrays, scene, options=None, edit=None):
    """(layers, counts) of the route and of the generic route for the same passes and plan; the
    route must have run on every material it applies to."""
    options = options or {}
    passes = Passes(arrays)
    taken = []

    def spy(*args):
        result = sta_technique.composite(*args)
        taken.append(result is not None)
        return result

    spy.computes = STA.function  # the route of STA's function (Technique.composite)

    out = []
    for spec in (dataclasses.replace(STA, composite=spy), GENERIC):
        with backend.use("numba"):
            p = plan(passes, scene, spec, **options)
            if edit is not None:
                edit(p)
            layers = core_apply.apply(passes, scene, spec, prepared=p, **options)
        counts = (p.nonfinite_pixels, p.overflow_pixels, p.negative_pixels, p.fractional_index_pixels)
        out.append((layers, counts))
    assert taken and all(taken), "the route did not run"
    return out


def _assert_same_bits(route, generic):
    (layers, counts), (expected, expected_counts) = route, generic
    assert counts == expected_counts
    assert layers.keys() == expected.keys()
    for name in layers:
        assert layers[name].dtype == expected[name].dtype and layers[name].shape == expected[name].shape
        assert layers[name].tobytes() == expected[name].tobytes(), name


@needs_numba
@pytest.mark.parametrize("lights", list(LIGHT_SETS))
@pytest.mark.parametrize(
    "options",
    [{}, {"falloff": "map"}, {"falloff": "burley"}, {"power": 0.0, "ambient": 0.2}, {"power": 3.5, "distortion": 0.6}],
    ids=["medium", "map", "burley", "power 0, ambient", "power 3.5"],
)
def test_route_gives_the_generic_routes_bits(lights, options):
    arrays, scene = _frame()
    scene = dataclasses.replace(scene, lights=LIGHT_SETS[lights])
    route, generic = _both(arrays, scene, options)
    _assert_same_bits(route, generic)
    sss = route[0]["SSSLab.sta.SSS"]
    if lights == "no light":
        assert not sss.any()
    else:
        assert (sss > 0).any()  # the route composited light, not an untouched frame


@needs_numba
@pytest.mark.parametrize("rgb", [False, True], ids=["RGBA", "RGB"])
@pytest.mark.parametrize("convention", ["translucency", "thickness"])
def test_nan_inf_and_negative_inputs_as_the_generic_route(rgb, convention):
    """NaN and infinities in each pass the route reads leave their pixels as they are and are
    counted; a NaN alpha does not; negative Combined, albedo below 0 (whose negative term turns
    Combined negative: clamped to 0 and counted) and fractional Material Index values alike."""
    arrays, scene = _frame(rgb=rgb)
    scene = dataclasses.replace(scene, thickness_convention=convention)
    mi = arrays["Material Index"]
    ys, xs = np.nonzero(mi == 2)
    pick = iter(range(0, len(ys), 7))
    for name, channel, value in [
        ("Diffuse Color", 0, np.nan),
        ("Normal", 1, np.inf),
        ("Position", 2, -np.inf),
        ("Thickness", None, np.nan),
        ("Combined", 1, np.nan),
        ("Combined", 2, np.inf),
    ]:
        k = next(pick)
        a = arrays[name]
        if channel is None:
            a[ys[k], xs[k]] = value
        else:
            a[ys[k], xs[k], channel] = value
    if not rgb:
        k = next(pick)
        arrays["Combined"][ys[k], xs[k], 3] = np.nan  # alpha: not an input of the technique
    for _ in range(5):  # negative Combined
        k = next(pick)
        arrays["Combined"][ys[k], xs[k], :3] = -0.25
    k = next(pick)
    arrays["Combined"][ys[k], xs[k], 0] = -0.0
    for _ in range(6):  # a negative albedo: a negative term, clamped where Combined is >= 0
        k = next(pick)
        arrays["Diffuse Color"][ys[k], xs[k]] = (-50.0, 0.3, -50.0)
    for value in (2.4, 1.6, 2.5, 3.49, np.nan, np.inf):  # 2.5 rounds to 2 (half to even)
        k = next(pick)
        mi[ys[k], xs[k]] = value
    route, generic = _both(arrays, scene)
    _assert_same_bits(route, generic)
    nonfinite, overflow, negative, fractional = route[1]
    assert nonfinite == 6 and negative > 0 and fractional == 4 and overflow == 0


@needs_numba
@pytest.mark.parametrize(
    "gain", [None, (1.5, 1.0, 0.25), 2.0, (-1.0, 1.0, 3e38)], ids=["none", "per channel", "one", "negative, huge"]
)
@pytest.mark.parametrize("weight", [1.0, 0.6], ids=["weight 1", "weight 0.6"])
def test_gain_weight_and_overflow_as_the_generic_route(gain, weight):
    """A fitted gain (here set on the plan, as a fit would) and a Subsurface Weight below 1 scale
    the result as the generic route does; light near float32's limit (an albedo of 1e38 with an
    ambient of 10 and the paper's falloff, a gain of 3e38) overflows there: those pixels are left
    as they were and counted."""
    arrays, scene = _frame(weight=weight)
    mi = arrays["Material Index"]
    ys, xs = np.nonzero(mi == 3)
    arrays["Diffuse Color"][ys[::5], xs[::5]] = 1e38  # 3e38 would overflow the sum STA tests its inputs by

    def edit(p):
        for mp in p.applied:
            if gain is None:
                mp.params.pop("gain", None)
            else:
                mp.params["gain"] = gain

    with np.errstate(over="ignore", invalid="ignore"):
        route, generic = _both(arrays, scene, {"ambient": 10.0, "falloff": "map"}, edit=edit)
    _assert_same_bits(route, generic)
    assert route[1][1] > 0  # overflowed pixels, left as they were
    if gain is not None and np.ndim(gain) and gain[0] < 0:
        assert route[1][2] > 0  # a negative gain's term turns Combined's red negative: clamped


@needs_numba
def test_per_pixel_weight_and_unusual_passes_keep_the_generic_route():
    """What the route does not take (a thickness AOV of three channels, a Subsurface Weight per
    pixel) runs on the generic route: ``composite`` returns None there and ``apply`` gives the
    generic route's bits."""
    arrays, scene = _frame()
    passes = Passes(arrays)
    image = np.array(arrays["Combined"])
    sss = np.zeros(image.shape[:2] + (3,), np.float32)
    params = plan(passes, scene, "sta").applied[0].params
    with backend.use("numba"):
        assert sta_technique.composite(passes, scene, 2, image, sss, None, None, params) is not None
        three = Passes({**arrays, "Thickness": np.repeat(arrays["Thickness"][..., None], 3, axis=2)})
        assert sta_technique.composite(three, scene, 2, image, sss, None, None, params) is None
        assert sta_technique.composite(passes, scene, 2, image, sss, np.ones((2, 2)), None, params) is None
        assert sta_technique.composite(passes, scene, 1 << 24, image, sss, None, None, params) is None
        with backend.use("numpy"):
            assert sta_technique.composite(passes, scene, 2, image, sss, None, None, params) is None
        layers = core_apply.apply(three, scene, "sta")
        expected = core_apply.apply(three, scene, GENERIC)
    assert all(layers[k].tobytes() == expected[k].tobytes() for k in layers)


@needs_numba
def test_check_mode_compares_the_routes_to_the_bit(monkeypatch):
    """In check mode ``apply`` runs both routes and raises ``BackendMismatch`` where their bits
    differ: a route that is off by one unit in the last place on one pixel is caught."""
    arrays, scene = _frame()
    passes = Passes(arrays)

    def off_by_one_ulp(passes, scene, index, image, sss, gain, weight, params):
        result = sta_technique.composite(passes, scene, index, image, sss, gain, weight, params)
        ys, xs = np.nonzero(np.any(sss != 0, axis=2))
        image[ys[0], xs[0], 0] = np.nextafter(image[ys[0], xs[0], 0], np.float32(np.inf))
        return result

    off_by_one_ulp.computes = STA.function
    with backend.use("check"):
        core_apply.apply(passes, scene, "sta")  # the real route: the same bits, no error
        with pytest.raises(backend.BackendMismatch, match="route"):
            core_apply.apply(passes, scene, dataclasses.replace(STA, composite=off_by_one_ulp))
