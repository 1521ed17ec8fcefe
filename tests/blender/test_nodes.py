"""The compositor node groups (nodes/) run by Blender's compositor headless, against the NumPy passes.

Each case writes fixed passes (64 x 64) to a multilayer EXR with core.scene.exr, reads it with an
Image node (no Render Layers node, so Blender only composites), wires the technique's groups
with ``nodes.setup.build_chain`` (the wiring the Set Up Compositor operator uses), renders one
frame to a float32 EXR and reads it back. The NumPy result is ``core.pipeline.apply.apply`` on the same
passes with the same scene description and parameters.

Where the tolerances come from:

- STA, 1e-4 relative (the issue's bound): the group does core.techniques.sta.technique's float32 arithmetic node by
  node, so the two differ by float32 rounding (measured: below 1e-6 relative).
- SSSS at constant depth: the kernel images hold exactly core.techniques.ssss.technique's interpolation weights
  (``core.optics.kernel_images``) and the masking formula reproduces its "off-mask weight goes to the
  centre" rule, so the two compute the same sums; what is left is float32 rounding and the
  Convolve node's FFT (round-off of order eps * log2(N) per convolution, eps = 6e-8, N about
  2^13 pixels of the padded 64 x 64 image, four convolutions in a chain: about 3e-6 of the
  image's largest value). Asserted: 1e-5 of the largest value, away from the image border (where
  core.techniques.ssss.technique reads the edge pixel and the Convolve node reads zeros; that difference is measured
  and printed).
- Burley at constant depth: the group convolves with the exact profile, core.techniques.burley.technique sums
  ``n_samples`` spiral samples. Both are linear and shift-invariant there, so on a quadratic
  image their difference is fixed by their kernels' first and second moments:
  numpy - group = A (grad E . (m1_np - m1_K) + 1/2 tr(H (M2_np - M2_K))), with the NumPy
  kernel measured as core.techniques.burley.technique's response to an impulse. The tolerance is that prediction
  plus 1e-5 of the largest value (the FFT bound above). A textured image checks the group
  against a NumPy model of the same convolutions (``core.optics.kernel_images.correlate_zero``).
- Depth-varying surfaces are measured and printed, not asserted (docs/compositor.md has the figures).
"""

import dataclasses
import inspect
import math
import os

import bpy
import numpy as np
import pytest

from sss_lab.blender import compat
from sss_lab.core.optics.kernel_images import (
    blur_node_gaussian,
    burley_gaussian_mixture,
    burley_kernel_image,
    correlate_zero,
    gaussian_mixture_image,
    separable_kernel_image,
)
from sss_lab.core.optics.kernels import make_kernel
from sss_lab.core.pipeline import mapping
from sss_lab.core.pipeline.apply import apply
from sss_lab.core.scene.exr import read_layers, read_passes, write_layers
from sss_lab.core.scene.scene import Camera, Light, MaterialSSS, SceneDescription
from sss_lab.core.techniques.burley import technique as np_burley
from sss_lab.core.techniques.ssss import technique as ssss
from sss_lab.core.techniques.sta import technique as sta
from sss_lab.nodes import _graph
from sss_lab.nodes.burley import ensure_burley_group
from sss_lab.nodes.setup import NODE_TAG, build_chain, group_name, remove_chain
from sss_lab.nodes.ssss import ensure_ssss_group
from sss_lab.nodes.sta import INTERFACE as STA_INTERFACE
from sss_lab.nodes.sta import ensure_sta_group

# Skipped where the groups cannot run (Blender 4.5; tests/blender/conftest.py).
pytestmark = pytest.mark.compositor_groups

W = H = 64
DEPTH = 2.0
CAMERA = Camera(width_px=W, height_px=H)  # at the origin, looking down -Z, 50 mm on a 36 mm sensor
SCALE = CAMERA.focal_px / DEPTH  # pixels per scene unit at the surfaces' depth (44.4)
# Burley d = radius x scale / (4 pi) (BURLEY method, no albedo fit): (0.016, 0.008, 0.004),
# so the kernels reach 16 d = 11.4 px; the second material reaches half as far.
SKIN = MaterialSSS(index=1, name="Skin", method="BURLEY", subsurface_radius=(1.0, 0.5, 0.25), subsurface_scale=0.201)
WAX = MaterialSSS(index=2, name="Wax", method="BURLEY", subsurface_radius=(0.5, 0.5, 0.4), subsurface_scale=0.201)
FFT_TOL = 1e-5
#: The node groups keep the passes' energy (docs/compositor.md): the NumPy techniques they are
#: compared with run with energy="lambert" (their default, "object", models Cycles' energy).
LAMBERT = {"energy": "lambert"}


# -- running the compositor --------------------------------------------------------------------


def _passes(materials_map, *, seed=0, diffuse=None, albedo=None):
    """Fixed passes: ``materials_map`` (H, W) holds the material index of each pixel (0: none)."""
    rng = np.random.default_rng(seed)
    on = materials_map > 0
    e = rng.uniform(0.0, 1.5, (H, W, 3)).astype(np.float32) if diffuse is None else diffuse
    ind = np.zeros((H, W, 3), np.float32) if diffuse is not None else rng.uniform(0, 0.5, (H, W, 3)).astype(np.float32)
    a = rng.uniform(0.2, 0.9, (H, W, 3)).astype(np.float32) if albedo is None else albedo
    rows, cols = np.mgrid[:H, :W].astype(np.float32)
    ray = np.stack(
        [(cols + 0.5 - W / 2) / CAMERA.focal_px, -(rows + 0.5 - H / 2) / CAMERA.focal_px, -np.ones_like(rows)], -1
    )
    position = (ray * DEPTH).astype(np.float32)
    normal = rng.normal(size=(H, W, 3)).astype(np.float32)
    normal[..., 2] = np.abs(normal[..., 2]) + 0.5  # mostly facing the camera
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    combined = np.ones((H, W, 4), np.float32)
    combined[..., :3] = a * (e + ind) + rng.uniform(0, 0.2, (H, W, 3)).astype(np.float32)  # + some glossy
    return {
        "Combined": combined,
        "Diffuse Direct": e,
        "Diffuse Indirect": ind,
        "Diffuse Color": a,
        "Depth": np.where(on, DEPTH, 1e10).astype(np.float32),
        "Normal": normal,
        "Position": position,
        "Material Index": materials_map.astype(np.float32),
        "Object Index": materials_map.astype(np.float32),
        "Thickness": rng.uniform(0, 1, (H, W)).astype(np.float32),
    }


def _write(tmp_path, arrays, name="passes.exr"):
    path = str(tmp_path / name)
    write_layers(path, {f"ViewLayer.{k}": v for k, v in arrays.items()}, overwrite=True)
    return path


def _tree(scene):
    tree = compat.compositor_tree(scene, create=True)
    return tree, compat.compositor_result_socket(tree)


def _source(tree, path):
    node = tree.nodes.new("CompositorNodeImage")
    node.image = bpy.data.images.load(path, check_existing=True)
    return node


def _render(tmp_path, name="out.exr"):
    scene = bpy.context.scene
    render = scene.render
    render.resolution_x, render.resolution_y, render.resolution_percentage = W, H, 100
    render.use_compositing = True
    compat.set_compositor_device(scene, "CPU")
    compat.set_single_image(render.image_settings, "OPEN_EXR", color_depth="32")
    scene.view_settings.view_transform = "Standard"
    render.filepath = str(tmp_path / name)
    if os.path.exists(render.filepath):
        os.remove(render.filepath)
    bpy.ops.render.render(write_still=True)
    (layer,) = read_layers(render.filepath).layers.values()
    return np.array(layer[..., :3])


def _composite(tmp_path, arrays, desc, technique, options=None, scale=None, numpy_only=None, group_only=None):
    """Run ``technique``'s chain over ``arrays``; returns (Blender's RGB, NumPy's RGB).
    ``numpy_only``: options for the NumPy technique alone (the node group has no such input);
    ``group_only``: options for the node group alone (its route)."""
    path = _write(tmp_path, arrays)
    tree, result = _tree(bpy.context.scene)
    src = _source(tree, path)
    if scale is None:
        scale = {m.index: SCALE for m in desc.materials}
    out, notes = build_chain(
        tree,
        src,
        image=src.outputs["Combined"],
        technique=technique,
        scene=desc,
        options={**(options or {}), **(group_only or {})},
        pixels_per_unit=scale,
    )
    assert not notes
    tree.links.new(out, result)
    got = _render(tmp_path)
    numpy_opts = {**(options or {}), **(numpy_only or {})}
    layers = apply(read_passes(path), desc, technique, **numpy_opts)
    want = layers[f"SSSLab.{technique}.Image"][..., :3]
    return got, want


def _desc(*materials, lights=()):
    return SceneDescription(camera=CAMERA, lights=tuple(lights), materials=materials)


def _rel_rms(a, b, mask):
    return float(np.sqrt(np.mean((a[mask] - b[mask]) ** 2)) / max(np.sqrt(np.mean(b[mask] ** 2)), 1e-30))


# -- the Convolve node's conventions (docs/compositor.md relies on them) -------------------------


def _convolve_once(tmp_path, image, kernel):
    tree, result = _tree(bpy.context.scene)
    src = tree.nodes.new("CompositorNodeImage")
    src.image = _graph.ensure_image("probe image", image, owner="probe")
    ker = tree.nodes.new("CompositorNodeImage")
    ker.image = _graph.ensure_image("probe kernel", kernel, owner="probe")
    node, image_in, kernel_in, output = compat.new_convolve(tree, color_kernel=True, normalize=False)
    tree.links.new(src.outputs["Image"], image_in)
    tree.links.new(ker.outputs["Image"], kernel_in)
    tree.links.new(output, result)
    return _render(tmp_path)


def test_convolve_node_gathers_per_channel_with_zero_borders(tmp_path):
    image = np.zeros((64, 64, 3), np.float32)
    image[30, 40] = 1.0  # an impulse: the output shows the kernel mirrored (a gather)
    image[:, 0] = 2.0  # a bright left column: what the border does
    kernel = np.zeros((3, 5, 3), np.float32)
    kernel[1, 4, 0] = 1.0  # red: take the pixel two to the right
    kernel[0, 2, 1] = 1.0  # green: take the pixel one up
    kernel[1, 2, 2] = 0.5  # blue: half the pixel itself
    kernel[1, 0, 2] = 0.5  # ... plus half the pixel two to the left
    got = _convolve_once(tmp_path, image, kernel)
    assert got[30, 38, 0] == pytest.approx(1.0, abs=1e-5)  # out(p) = in(p + (0, +2))
    assert got[31, 40, 1] == pytest.approx(1.0, abs=1e-5)  # out(p) = in(p + (-1, 0)): row 0 is the top
    assert got[30, 40, 2] == pytest.approx(0.5, abs=1e-5) and got[30, 42, 2] == pytest.approx(0.5, abs=1e-5)
    # Red at the last two columns would read beyond the right border: zeros, no clamping.
    assert np.abs(got[:, 62:, 0]).max() < 1e-5
    # Blue: column 2 reads itself (0) and column 0 (2); column 0 reads itself (2) and column -2,
    # which is zero; column 1 reads itself and column -1: nothing.
    assert got[10, 2, 2] == pytest.approx(1.0, abs=1e-5)
    assert got[10, 0, 2] == pytest.approx(1.0, abs=1e-5)
    assert abs(got[10, 1, 2]) < 1e-5
    # FFT round-off far from everything: tiny.
    assert np.abs(got[5:25, 10:30]).max() < 1e-5


# -- STA ----------------------------------------------------------------------------------------


def _lights():
    def m(loc, rot_x):
        c, s = math.cos(rot_x), math.sin(rot_x)
        r = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
        out = np.eye(4)
        out[:3, :3], out[:3, 3] = r, loc
        return tuple(out.ravel())

    return [
        Light(type="SUN", name="Sun", energy=3.0, color=(1.0, 0.9, 0.8), matrix_world=m((0, 0, -5), math.pi * 0.9)),
        Light(type="POINT", name="Point", energy=40.0, color=(0.6, 0.8, 1.0), matrix_world=m((0.3, 0.2, -3.0), 0)),
        Light(
            type="SPOT",
            name="Spot",
            energy=80.0,
            matrix_world=m((0.0, 0.0, -3.5), math.pi),
            spot_size=math.radians(30.0),
            spot_blend=0.4,
        ),
        Light(type="AREA", name="Area", energy=60.0, matrix_world=m((-0.4, 0.1, -3.2), math.pi * 0.95)),
    ]


def _two_materials():
    rows, cols = np.mgrid[:H, :W]
    index = np.zeros((H, W), np.int32)
    skin = (cols < 40) & ((cols - 20) ** 2 + (rows - 32) ** 2 > 36)
    index[skin] = 1
    index[(cols >= 44) & (rows >= 8) & (rows < 56)] = 2
    return index


@pytest.mark.parametrize("convention", ["translucency", "thickness"])
def test_sta_matches_numpy(tmp_path, convention):
    arrays = _passes(_two_materials(), seed=1)
    desc = SceneDescription(
        camera=CAMERA, lights=tuple(_lights()), materials=(SKIN, WAX), thickness_convention=convention
    )
    options = {"distortion": 0.3, "power": 3.0, "scale": 2.0, "ambient": 0.05}
    # The group is the paper's STA (docs/compositor.md): NumPy's default falloff filters through the medium.
    got, want = _composite(tmp_path, arrays, desc, "sta", options, numpy_only={"falloff": "map"})
    term = want - arrays["Combined"][..., :3]
    on = arrays["Material Index"] > 0
    assert term[on].max() > 0.01 and (term[on] > 1e-4).mean() > 0.5  # the lights do reach the surface
    # 1e-4 relative to each pixel's translucency (a 1e-6 floor for pixels the lobe barely reaches).
    err = np.abs(got - want)
    assert np.all(err <= 1e-4 * np.abs(term) + 1e-6 * term.max()), float(err.max())
    assert np.array_equal(got[~on], want[~on]) or np.abs(got[~on] - want[~on]).max() < 1e-6


# -- SSSS ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "options",
    [
        {"kernel_type": "preintegrated", "n_taps": 17, "albedo_mode": "post"},
        {"kernel_type": "artist", "n_taps": 25, "albedo_mode": "pre-post"},
        {"kernel_type": "preintegrated", "n_taps": 11, "albedo_mode": "pre-post"},
    ],
)
def test_ssss_flat_matches_numpy(tmp_path, options):
    index = _two_materials()
    arrays = _passes(index, seed=2)
    desc = _desc(SKIN, WAX)
    got, want = _composite(tmp_path, arrays, desc, "ssss", options, numpy_only=LAMBERT)
    radius = max(
        separable_kernel_image(
            make_kernel(options["kernel_type"], options["n_taps"], d_su=mapping.burley_d(m)), SCALE
        ).shape[0]
        // 2
        for m in (SKIN, WAX)
    )
    inner = np.zeros((H, W), bool)
    inner[radius:-radius, radius:-radius] = True
    top = np.abs(want).max()
    err = np.abs(got - want).max(axis=-1)
    assert np.abs(got - arrays["Combined"][..., :3])[index > 0].max() > 0.05  # it does scatter
    assert err[inner].max() <= FFT_TOL * top, float(err[inner].max())
    print(f"\nSSSS {options}: interior max |diff| {err[inner].max():.2e}, at the image border {err.max():.2e}")


# -- Burley -------------------------------------------------------------------------------------


#: core.techniques.burley.technique with the same spiral at every pixel: its gather is then one kernel, whose moments
#: this model uses (the default turns the spiral per pixel, a different kernel at each pixel, and takes fewer
#: samples where the light varies little: adaptive counts, docs/references.md §21).
FIXED_SPIRAL = {"random_rotation": False, "smooth_px": 0, "adaptive": False}


def _numpy_kernel_moments(d_su, n_samples=32):
    """First and second moments of core.techniques.burley.technique's gather kernel at constant depth (the fixed
    spiral), measured as its response to an impulse (W[o] = out(q - o)); offsets (dx right, dy
    down) in pixels."""
    q = (H // 2, W // 2)
    delta = np.zeros((H, W, 3), np.float32)
    delta[q] = 1.0
    out = np_burley.burley(
        diffuse=delta,
        albedo=np.ones((H, W, 3), np.float32),
        depth=np.full((H, W), DEPTH, np.float32),
        mask=np.ones((H, W), bool),
        camera=CAMERA,
        d_su=d_su,
        object_id=np.ones((H, W), np.float32),
        n_samples=n_samples,
        **FIXED_SPIRAL,
    ).astype(np.float64)
    rows, cols = np.mgrid[:H, :W]
    dy, dx = q[0] - rows, q[1] - cols  # out at p holds W[q - p]
    w = out
    assert np.allclose(w.sum(axis=(0, 1)), 1.0, atol=1e-5)
    return _moments(w, dx, dy)


def _moments(w, dx, dy):
    m = {}
    for name, f in (("x", dx), ("y", dy), ("xx", dx * dx), ("yy", dy * dy), ("xy", dx * dy)):
        m[name] = (w * f[..., None]).sum(axis=(0, 1))
    return m


def _kernel_moments(kernel):
    r = kernel.shape[0] // 2
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
    return _moments(kernel.astype(np.float64), dx, dy)


def test_burley_flat_quadratic_matches_numpy_by_the_kernel_moments(tmp_path):
    rows, cols = np.mgrid[:H, :W].astype(np.float64)
    u, v = (cols - 32) / 32, (rows - 32) / 32
    b = np.array([0.3, -0.2, 0.25])
    c = np.array([-0.15, 0.35, 0.1])
    q = np.array([0.4, 0.3, -0.2])
    t = np.array([0.2, -0.3, 0.15])
    e = 1.0 + b * u[..., None] + c * v[..., None] + q * (u * u + v * v)[..., None] + t * (u * v)[..., None]
    albedo = np.random.default_rng(3).uniform(0.3, 0.9, (H, W, 3)).astype(np.float32)
    arrays = _passes(np.ones((H, W), np.int32), seed=3, diffuse=e.astype(np.float32), albedo=albedo)
    got, want = _composite(tmp_path, arrays, _desc(SKIN), "burley", numpy_only={**FIXED_SPIRAL, **LAMBERT})
    d = mapping.burley_d(SKIN)
    kernel = burley_kernel_image(d, SCALE)
    mk, mn = _kernel_moments(kernel), _numpy_kernel_moments(d)
    gx = (b + 2 * q * u[..., None] + t * v[..., None]) / 32
    gy = (c + 2 * q * v[..., None] + t * u[..., None]) / 32
    hxx = hyy = 2 * q / 1024
    hxy = t / 1024
    dm = {k: mn[k] - mk[k] for k in mn}
    predicted = albedo * (
        gx * dm["x"] + gy * dm["y"] + 0.5 * (hxx * dm["xx"] + hyy * dm["yy"]) + hxy * dm["xy"]
    )  # numpy - group
    r = kernel.shape[0] // 2
    inner = np.zeros((H, W), bool)
    inner[r:-r, r:-r] = True
    diff = (want - got)[inner]
    assert np.abs(got - arrays["Combined"][..., :3])[inner].max() > 1e-3  # it does scatter the curved image
    assert np.abs(diff - predicted[inner]).max() <= FFT_TOL * np.abs(want).max()
    print(
        f"\nBurley quadratic image: |numpy(32) - group| max {np.abs(diff).max():.2e}, "
        f"predicted from the moments {np.abs(predicted[inner]).max():.2e}; second moments (R) "
        f"numpy {mn['xx'][0] + mn['yy'][0]:.3f} px^2, group {mk['xx'][0] + mk['yy'][0]:.3f} px^2"
    )


def test_burley_textured_matches_the_convolution_model_and_is_measured_against_numpy(tmp_path):
    index = _two_materials()
    arrays = _passes(index, seed=4)
    desc = _desc(SKIN, WAX)
    got, want = _composite(tmp_path, arrays, desc, "burley", {"albedo_mode": "post"}, numpy_only=LAMBERT)
    # The NumPy model of the chain: per material, conv(E M) / conv(M) with the same kernel image.
    model = arrays["Combined"][..., :3].astype(np.float64)
    e = (arrays["Diffuse Direct"] + arrays["Diffuse Indirect"]).astype(np.float64)
    a = arrays["Diffuse Color"].astype(np.float64)
    for m in (SKIN, WAX):
        mask = (index == m.index).astype(np.float64)[..., None].repeat(3, -1)
        k = burley_kernel_image(mapping.burley_d(m), SCALE)
        scattered = correlate_zero(e * mask, k) / np.maximum(correlate_zero(mask, k), 1e-30)
        model += mask * (a * scattered - a * e)
    assert np.abs(got - model).max() <= FFT_TOL * np.abs(model).max()
    on = index > 0
    sss_np, sss_group = (want - arrays["Combined"][..., :3]), (got - arrays["Combined"][..., :3])
    many = apply(read_passes(str(tmp_path / "passes.exr")), desc, "burley", n_samples=1024)["SSSLab.burley.Image"]
    sss_many = many[..., :3] - arrays["Combined"][..., :3]
    print(
        "\nBurley textured, flat: relative RMS of the SSS term, group vs numpy(32) "
        f"{_rel_rms(sss_group, sss_np, on):.3f}, vs numpy(1024) {_rel_rms(sss_group, sss_many, on):.3f}"
    )


# -- the Blur-node route ---------------------------------------------------------------------------


def test_blur_node_is_the_cut_gaussian_of_the_kernel_module(tmp_path):
    """The Blur node's Gaussian at integer sizes, as ``blur_node_gaussian`` models it, on all four
    channels (the route carries the mask in alpha)."""
    for size in (2, 7):
        image = np.zeros((H, W, 4), np.float32)
        image[32, 32] = 1.0
        tree, result = _tree(bpy.context.scene)
        src = tree.nodes.new("CompositorNodeImage")
        src.image = _graph.ensure_image("probe image", image, owner="probe")
        node, image_in, output = compat.new_gaussian_blur(tree, size)
        tree.links.new(src.outputs["Image"], image_in)
        tree.links.new(output, result)
        got = _render(tmp_path, f"blur{size}.exr")
        line = blur_node_gaussian(size)
        want = np.zeros((H, W))
        want[32 - size : 33 + size, 32 - size : 33 + size] = np.outer(line, line)
        np.testing.assert_allclose(got[..., 0], want, atol=1e-6)
        (layer,) = read_layers(str(tmp_path / f"blur{size}.exr")).layers.values()
        np.testing.assert_allclose(np.asarray(layer)[..., 3], want, atol=1e-6)  # alpha blurred alike


def test_burley_gaussians_route_is_its_mixture_and_near_the_exact_group(tmp_path):
    """The Blur-node route computes sum_k w_k G_k(E M) / sum_k w_k G_k(M) per material with the
    mixture of ``burley_gaussian_mixture`` (asserted against that model in NumPy away from the
    border, where the Blur node's own border rule applies; 1e-5 of the largest value: float32
    sums of a few hundred taps per pass), and its SSS term is measured against the exact group's."""
    index = _two_materials()
    arrays = _passes(index, seed=4)
    desc = _desc(SKIN, WAX)
    got, _ = _composite(tmp_path, arrays, desc, "burley", numpy_only=LAMBERT, group_only={"route": "gaussians"})
    model = arrays["Combined"][..., :3].astype(np.float64)
    e = (arrays["Diffuse Direct"] + arrays["Diffuse Indirect"]).astype(np.float64)
    a = arrays["Diffuse Color"].astype(np.float64)
    radius = 0
    for m in (SKIN, WAX):
        mask = (index == m.index).astype(np.float64)[..., None].repeat(3, -1)
        sizes, weights = burley_gaussian_mixture(mapping.burley_d(m), SCALE)
        assert 1 <= len(sizes) <= 6
        k = gaussian_mixture_image(sizes, weights)
        radius = max(radius, k.shape[0] // 2)
        scattered = correlate_zero(e * mask, k) / np.maximum(correlate_zero(mask, k), 1e-30)
        model += mask * (a * scattered - a * e)
    inner = (slice(radius, -radius), slice(radius, -radius))
    assert np.abs(got - model)[inner].max() <= FFT_TOL * np.abs(model).max()
    exact, _ = _composite(tmp_path, arrays, desc, "burley", numpy_only=LAMBERT)
    on = index > 0
    base = arrays["Combined"][..., :3]
    inner_on = np.zeros_like(on)
    inner_on[inner] = on[inner]
    print(
        "\nBurley, Blur-node route against the Convolve route: relative RMS of the SSS term "
        f"{_rel_rms(got - base, exact - base, inner_on):.4f} inside, {_rel_rms(got - base, exact - base, on):.4f} "
        "with the border"
    )


# -- depth-varying surfaces: measured, not asserted ----------------------------------------------


@pytest.mark.parametrize("technique", ["ssss", "burley"])
def test_depth_varying_is_measured(tmp_path, technique):
    """A plane tilted from depth 1.5 to 2.5 and a step between depths 1.6 and 2.4 (one material):
    the group uses the screen scale at depth 2 everywhere and ignores depth jumps."""
    rows, cols = np.mgrid[:H, :W]
    index = np.ones((H, W), np.int32)
    arrays = _passes(index, seed=5)
    figures = {}
    for case, depth in (
        ("tilted", 1.5 + cols / (W - 1.0)),
        ("step", np.where(cols < W // 2, 1.6, 2.4)),
    ):
        arrays["Depth"] = depth.astype(np.float32)
        got, want = _composite(tmp_path, arrays, _desc(SKIN), technique, numpy_only=LAMBERT)
        combined = arrays["Combined"][..., :3]
        inner = np.zeros((H, W), bool)
        inner[12:-12, 12:-12] = True
        figures[case] = round(_rel_rms(got - combined, want - combined, inner), 4)
        if technique == "burley":  # without the 32-sample spiral's own error
            many = apply(read_passes(str(tmp_path / "passes.exr")), _desc(SKIN), technique, n_samples=1024, **LAMBERT)[
                "SSSLab.burley.Image"
            ]
            figures[f"{case} (numpy 1024 samples)"] = round(
                _rel_rms(got - combined, many[..., :3] - combined, inner), 4
            )
        bpy.ops.wm.read_factory_settings(use_empty=True)
    print(f"\n{technique} depth-varying: relative RMS of the SSS term vs numpy: {figures}")
    assert all(np.isfinite(v) for v in figures.values())


# -- builders: idempotent, parameters, save and reload --------------------------------------------


def _counts():
    return (len(bpy.data.node_groups), len(bpy.data.images))


def test_builders_are_idempotent():
    d = mapping.burley_d(SKIN)
    (
        ensure_sta_group(),
        ensure_ssss_group(pixels_per_unit=SCALE, d_su=d),
        ensure_burley_group(d_su=d, pixels_per_unit=SCALE),
    )
    first = _counts()
    sizes = {g.name: (len(g.nodes), len(g.links), len(g.interface.items_tree)) for g in bpy.data.node_groups}
    (
        ensure_sta_group(),
        ensure_ssss_group(pixels_per_unit=SCALE, d_su=d),
        ensure_burley_group(d_su=d, pixels_per_unit=SCALE),
    )
    assert _counts() == first == (3, 3)
    assert sizes == {g.name: (len(g.nodes), len(g.links), len(g.interface.items_tree)) for g in bpy.data.node_groups}


def test_rebuilding_with_other_parameters_updates_the_kernel_in_place():
    g1 = ensure_burley_group(d_su=(0.01, 0.005, 0.002), pixels_per_unit=SCALE)
    g2 = ensure_burley_group(d_su=(0.02, 0.01, 0.004), pixels_per_unit=SCALE)
    assert g1 == g2 and _counts() == (1, 1)
    image = bpy.data.images["SSS Lab Burley kernel"]
    want = burley_kernel_image((0.02, 0.01, 0.004), SCALE)
    np.testing.assert_array_equal(_graph.image_pixels(image)[..., :3], want)
    assert _graph.read_meta(g2)["d_su"] == pytest.approx([0.02, 0.01, 0.004])


def _socket_defaults(group):
    out = {}
    for item in group.interface.items_tree:
        if item.item_type == "SOCKET" and item.in_out == "INPUT":
            value = item.default_value
            out[item.name] = value if isinstance(value, (str, float, int)) else tuple(value)
    return out


def test_group_inputs_have_the_numpy_names_and_defaults():
    d = mapping.burley_d(SKIN)
    sta_defaults = _socket_defaults(ensure_sta_group())
    # STA's falloffs through the medium (its default) and Burley's transmittance are NumPy-only
    # (docs/compositor.md): the group is the paper's STA, whose thickness map scales all channels alike.
    numpy_only = {
        "falloff", "d_su", "thickness_distance_su", "mfp_su", "subsurface_method", "base_color",
        "subsurface_ior", "subsurface_anisotropy",
    }  # fmt: skip
    for name, param in inspect.signature(sta.sta).parameters.items():
        if param.default is not inspect.Parameter.empty and name not in numpy_only:
            if isinstance(param.default, str):
                assert sta_defaults[name] == param.default
            else:
                assert sta_defaults[name] == pytest.approx(param.default)
    assert {p.name for p in sta.TECHNIQUE.params if p.type is float} | {
        "thickness_convention",
        "albedo",
        "normal",
        "position",
        "thickness",
        "mask",
    } <= set(sta_defaults)
    assert sta_defaults["thickness_convention"] == "translucency"
    for group, func in (
        (ensure_ssss_group(pixels_per_unit=SCALE, d_su=d), ssss.ssss),
        (ensure_burley_group(d_su=d, pixels_per_unit=SCALE), np_burley.burley),
    ):
        defaults = _socket_defaults(group)
        assert defaults["albedo_mode"] == inspect.signature(func).parameters["albedo_mode"].default == "post"
        assert {"diffuse", "albedo", "mask"} <= set(defaults)
    # Build parameters: the builder's keywords carry ssss()'s names and defaults.
    builder = inspect.signature(ensure_ssss_group).parameters
    numpy_side = inspect.signature(ssss.ssss).parameters
    for name in ("kernel_type", "n_taps", "d_su", "unit_su", "falloff", "strength"):
        assert builder[name].default == numpy_side[name].default


def _chain_scene(tmp_path, technique, options):
    index = _two_materials()
    path = _write(tmp_path, _passes(index, seed=6))
    tree, result = _tree(bpy.context.scene)
    src = _source(tree, path)
    desc = SceneDescription(camera=CAMERA, lights=tuple(_lights()[:2]), materials=(SKIN, WAX))
    out, _ = build_chain(
        tree,
        src,
        image=src.outputs["Combined"],
        technique=technique,
        scene=desc,
        options=options,
        pixels_per_unit={1: SCALE, 2: SCALE},
    )
    tree.links.new(out, result)
    return tree


@pytest.mark.parametrize("technique", ["sta", "ssss", "burley"])
def test_parameters_and_result_survive_save_and_reload(tmp_path, technique):
    options = {"sta": {"distortion": 0.25, "power": 4.0}, "ssss": {"n_taps": 11, "albedo_mode": "pre-post"}}.get(
        technique, {"albedo_mode": "pre-post"}
    )
    tree = _chain_scene(tmp_path, technique, options)
    nodes = [n for n in tree.nodes if NODE_TAG in n.keys() and n.bl_idname == compat.COMPOSITOR_GROUP_NODE]
    assert nodes
    if technique == "sta":
        nodes[0].inputs["scale"].default_value = 1.75
    values = {n.name: {s.name: _value(s) for s in n.inputs if not s.is_linked} for n in nodes}
    groups = {n.node_tree.name: (_graph.read_meta(n.node_tree), _socket_defaults(n.node_tree)) for n in nodes}
    images = {i.name: _graph.image_pixels(i) for i in bpy.data.images if i.name.startswith("SSS Lab")}
    before = _render(tmp_path, "before.exr")
    blend = str(tmp_path / "setup.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=blend)
    tree = compat.compositor_tree(bpy.context.scene)
    nodes = [n for n in tree.nodes if NODE_TAG in n.keys() and n.bl_idname == compat.COMPOSITOR_GROUP_NODE]
    assert {n.name: {s.name: _value(s) for s in n.inputs if not s.is_linked} for n in nodes} == values
    assert {n.node_tree.name: (_graph.read_meta(n.node_tree), _socket_defaults(n.node_tree)) for n in nodes} == groups
    for name, pixels in images.items():
        np.testing.assert_array_equal(_graph.image_pixels(bpy.data.images[name]), pixels)
    np.testing.assert_array_equal(_render(tmp_path, "after.exr"), before)
    if technique == "sta":
        assert values[nodes[0].name]["distortion"] == pytest.approx(0.25)
        assert values[nodes[0].name]["scale"] == pytest.approx(1.75)
    else:
        assert all(v["albedo_mode"] == "pre-post" for v in values.values())


def _value(socket):
    v = socket.default_value
    return v if isinstance(v, (str, float, int, bool)) else tuple(round(x, 6) for x in v)


def test_remove_chain_restores_the_links():
    tree, result = _tree(bpy.context.scene)
    img = tree.nodes.new("CompositorNodeImage")
    grade = tree.nodes.new("CompositorNodeBrightContrast")
    tree.links.new(img.outputs["Image"], grade.inputs[0])
    tree.links.new(grade.outputs[0], result)
    assert remove_chain(tree) == 0
    assert grade.inputs[0].links[0].from_node == img


# -- the operator ---------------------------------------------------------------------------------


def _cycles_scene():
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -4.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = cam
    for name, x in (("Skin", -1.0), ("Wax", 1.0)):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([(-0.5, 0, -0.5), (0.5, 0, -0.5), (0.5, 0, 0.5), (-0.5, 0, 0.5)], [], [(0, 1, 2, 3)])
        obj = bpy.data.objects.new(name, mesh)
        obj.location = (x, 0.0, 0.0)
        scene.collection.objects.link(obj)
        mat = bpy.data.materials.new(name)
        compat.ensure_node_tree(mat)
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        bsdf.inputs["Subsurface Weight"].default_value = 0.0 if name == "Wax" else 1.0
        mesh.materials.append(mat)
    # Wax has no subsurface: only Skin scatters.
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    tree, result = _tree(scene)
    rl = tree.nodes.new("CompositorNodeRLayers")
    grade = tree.nodes.new("CompositorNodeBrightContrast")
    grade.name = "My Grade"
    tree.links.new(rl.outputs["Image"], grade.inputs[0])
    tree.links.new(grade.outputs[0], result)
    return scene, tree, grade


def test_operator_inserts_the_groups_and_keeps_the_users_nodes(addon):
    scene, tree, grade = _cycles_scene()
    assert bpy.ops.sss_lab.setup_compositor(technique="burley") == {"FINISHED"}
    names = sorted(n.name for n in tree.nodes)
    assert "My Grade" in names and group_name("burley", "Skin") in names
    assert grade.inputs[0].links[0].from_node.name == group_name("burley", "Skin")
    first = (names, len(tree.links), _counts())
    assert bpy.ops.sss_lab.setup_compositor(technique="burley") == {"FINISHED"}  # twice: nothing doubled
    assert (sorted(n.name for n in tree.nodes), len(tree.links), _counts()) == first
    assert bpy.ops.sss_lab.setup_compositor(technique="ssss") == {"FINISHED"}  # another technique replaces it
    names = sorted(n.name for n in tree.nodes)
    assert group_name("ssss", "Skin") in names and group_name("burley", "Skin") not in names and "My Grade" in names
    layer = scene.view_layers[0]
    assert layer.use_pass_diffuse_direct and layer.use_pass_material_index
    assert bpy.data.materials["Skin"].pass_index == 1
    # Removing SSS Lab's nodes gives the user's tree back.
    remove_chain(tree)
    assert grade.inputs[0].links[0].from_node.bl_idname == "CompositorNodeRLayers"
    assert not [n for n in tree.nodes if NODE_TAG in n.keys()]


def test_operator_refuses_clearly(addon):
    scene, tree, _ = _cycles_scene()
    assert bpy.ops.sss_lab.setup_compositor.poll()
    with pytest.raises(RuntimeError, match="bake thickness first"):
        bpy.ops.sss_lab.setup_compositor(technique="sta")  # no thickness map
    scene.render.engine = compat.eevee_engine()
    with pytest.raises(RuntimeError, match="set Render Engine to Cycles"):
        bpy.ops.sss_lab.setup_compositor(technique="burley")
    assert not [n for n in tree.nodes if NODE_TAG in n.keys()]


def test_bad_builder_input_is_refused():
    with pytest.raises(ValueError, match="d_su"):
        ensure_burley_group(d_su=(-1.0, 0.0, 0.0), pixels_per_unit=SCALE)
    with pytest.raises(ValueError, match="route: expected one of convolve, gaussians, got 'fft'"):
        ensure_burley_group(d_su=(0.01, 0.01, 0.01), pixels_per_unit=SCALE, route="fft")
    with pytest.raises(ValueError, match="pixels_per_unit"):
        ensure_ssss_group(pixels_per_unit=0.0, d_su=(0.01, 0.01, 0.01))
    with pytest.raises(ValueError, match="n_taps"):
        ensure_ssss_group(pixels_per_unit=SCALE, d_su=(0.01, 0.01, 0.01), n_taps=16)
    bpy.data.node_groups.new("SSS Lab STA", "GeometryNodeTree")
    with pytest.raises(ValueError, match="not a compositor node group"):
        ensure_sta_group()
    assert len(bpy.data.node_groups) == 1


def test_rebuild_keeps_links_and_values_of_the_instances_and_fixes_the_interface():
    group = ensure_sta_group()
    # An older or edited interface: a stray socket, one missing, one moved to the end.
    group.interface.new_socket("stray", in_out="INPUT", socket_type="NodeSocketFloat")
    group.interface.remove(next(s for s in group.interface.items_tree if getattr(s, "name", "") == "ambient"))
    moved = next(s for s in group.interface.items_tree if getattr(s, "name", "") == "distortion")
    group.interface.move(moved, len(group.interface.items_tree))
    before = [s.name for s in group.interface.items_tree if s.item_type == "SOCKET" and s.in_out == "INPUT"]
    assert "stray" in before and "ambient" not in before and before[-1] == "distortion"
    tree, result = _tree(bpy.context.scene)
    node = tree.nodes.new(compat.COMPOSITOR_GROUP_NODE)
    node.node_tree = group
    node.inputs["power"].default_value = 7.0
    node.inputs["light_type"].default_value = "AREA"
    tree.links.new(node.outputs["Image"], result)
    ensure_sta_group()
    names = [s.name for s in group.interface.items_tree if s.item_type == "SOCKET" and s.in_out == "INPUT"]
    assert names == [s.name for s in STA_INTERFACE.inputs]
    assert node.inputs["power"].default_value == 7.0 and node.inputs["light_type"].default_value == "AREA"
    assert node.inputs["ambient"].default_value == 0.0
    assert result.links[0].from_node == node


def test_operator_takes_the_panel_settings_and_the_panel_has_its_button(addon, draw_panels):

    scene, tree, _ = _cycles_scene()
    settings = scene.sss_lab
    settings.technique, settings.ssss.n_taps, settings.ssss.kernel_type = "ssss", "11", "artist"
    settings.albedo_mode = "pre-post"
    assert bpy.ops.sss_lab.setup_compositor() == {"FINISHED"}
    node = tree.nodes[group_name("ssss", "Skin")]
    meta = _graph.read_meta(node.node_tree)
    assert (meta["n_taps"], meta["kernel_type"]) == (11, "artist")
    assert node.inputs["albedo_mode"].default_value == "pre-post"
    # The screen scale: the quad is 4 units in front of the camera.
    assert meta["pixels_per_unit"] == pytest.approx(Camera(width_px=1920, height_px=1080).focal_px / 4.0, rel=1e-6)

    drawn = [(panel, name) for panel, _, name, _ in draw_panels("render")]
    assert ("Compositor", "sss_lab.setup_compositor") in drawn
    assert ("Compositor", "compositor_route") not in drawn  # SSSS has one route

    # Burley: the route is the panel's, and the panel shows it.
    settings.technique, settings.compositor_route = "burley", "gaussians"
    assert bpy.ops.sss_lab.setup_compositor() == {"FINISHED"}
    meta = _graph.read_meta(tree.nodes[group_name("burley", "Skin")].node_tree)
    assert meta["route"] == "gaussians" and 1 <= len(meta["blur_sizes"]) <= 6
    assert ("Compositor", "compositor_route") in [(p, n) for p, _, n, _ in draw_panels("render")]
    settings.compositor_route = "convolve"
    assert bpy.ops.sss_lab.setup_compositor() == {"FINISHED"}
    assert _graph.read_meta(tree.nodes[group_name("burley", "Skin")].node_tree)["route"] == "convolve"


@pytest.mark.parametrize("technique", ["burley", "ssss"])
def test_the_groups_say_what_they_cannot_read_per_pixel(addon, tmp_path, technique):
    """A material with inputs read per pixel from the render, and one with a Subsurface Weight
    below 1: the node groups are built from numbers and do not mix by the weight, and the set-up
    says so for each (Apply reads and mixes them)."""
    linked = dataclasses.replace(SKIN, per_pixel=("base_color", "subsurface_scale"))
    half = dataclasses.replace(WAX, subsurface_weight=0.5)
    materials_map = np.zeros((H, W))
    materials_map[:, : W // 2], materials_map[:, W // 2 :] = 1, 2
    path = _write(tmp_path, _passes(materials_map))
    tree, _ = _tree(bpy.context.scene)
    src = _source(tree, path)
    _, notes = build_chain(
        tree,
        src,
        image=src.outputs["Combined"],
        technique=technique,
        scene=_desc(linked, half),
        pixels_per_unit={1: SCALE, 2: SCALE},
    )
    assert any(n.startswith("Skin: base color, subsurface scale linked") and "per pixel" in n for n in notes)
    assert any(n.startswith("Wax: Subsurface Weight 0.5") and "mixes it by the weight" in n for n in notes)
    assert len(notes) == 2


def test_an_animated_lights_sta_group_follows_it_frame_by_frame(addon, tmp_path):
    """A sun turning 120 degrees between frames 1 and 3: the STA group set up at frame 1 takes the
    sun's frame-3 direction when the scene reaches frame 3 (the add-on's frame handler) and then
    matches ``apply`` on frame 3 within the STA tolerance above; without following, frame 1's
    light would be off by far more."""
    from sss_lab.blender.describe import describe_scene

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = W, H, 100
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam  # at the origin looking down -Z, as the passes' CAMERA
    mat = bpy.data.materials.new("Skin")
    compat.ensure_node_tree(mat)
    mat.node_tree.nodes["Principled BSDF"].inputs["Subsurface Weight"].default_value = 1.0
    mesh = bpy.data.meshes.new("Skin")
    mesh.from_pydata([(-1, -1, -2), (1, -1, -2), (0, 1, -2)], [], [(0, 1, 2)])
    mesh.materials.append(mat)
    scene.collection.objects.link(bpy.data.objects.new("Skin", mesh))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    scene.collection.objects.link(sun)
    for frame, angle in ((1, 0.9), (3, 0.9 - 2 / 3)):  # a 120 degree turn about X
        sun.rotation_euler = (math.pi * angle, 0.0, 0.0)
        sun.keyframe_insert("rotation_euler", frame=frame)
    scene.frame_set(1)
    lights1 = describe_scene(scene).lights

    arrays = _passes(_two_materials(), seed=1)
    desc = SceneDescription(camera=describe_scene(scene).camera, lights=lights1, materials=(SKIN, WAX))
    path = _write(tmp_path, arrays)
    tree, result = _tree(scene)
    src = _source(tree, path)
    options = {"distortion": 0.3, "power": 3.0, "scale": 2.0, "ambient": 0.05}
    out, notes = build_chain(tree, src, image=src.outputs["Combined"], technique="sta", scene=desc, options=options)
    assert not notes
    tree.links.new(out, result)

    scene.frame_set(3)
    lights3 = describe_scene(scene).lights
    (node,) = [n for n in tree.nodes if n.get(NODE_TAG) == "sta" and "sss_lab_light" in n.keys()]
    np.testing.assert_allclose(node.inputs["light_direction"].default_value, lights3[0].direction, atol=1e-6)
    got = _render(tmp_path)
    numpy_opts = {**options, "falloff": "map"}
    want = apply(read_passes(path), dataclasses.replace(desc, lights=lights3), "sta", **numpy_opts)
    want = want["SSSLab.sta.Image"][..., :3]
    stale = apply(read_passes(path), desc, "sta", **numpy_opts)["SSSLab.sta.Image"][..., :3]
    term = want - arrays["Combined"][..., :3]
    on = arrays["Material Index"] > 0
    assert term[on].max() > 0.01  # the sun reaches the surface at frame 3
    tol = 1e-4 * np.abs(term) + 1e-6 * term.max()
    assert np.abs(stale - want)[on].max() > 100 * tol[on].max()  # frame 1's light is far off
    assert np.all(np.abs(got - want) <= tol), float(np.abs(got - want).max())


def test_a_fitted_material_and_a_moved_camera_are_said_not_silently_ignored(tmp_path):
    """The groups use a fitted width, say that the fitted gain is Apply's alone, and say when a
    material's screen scale moved from the one its kernel was built for."""
    from sss_lab.nodes.setup import follow_scene

    fitted = dataclasses.replace(SKIN, fit={"ssss": {"d_scale": 2.0, "gain": (1.1, 1.0, 0.9)}})
    desc = _desc(fitted, WAX)
    tree, _ = _tree(bpy.context.scene)
    src = _source(tree, _write(tmp_path, _passes(_two_materials())))
    scale = {1: SCALE, 2: SCALE}
    _, notes = build_chain(
        tree, src, image=src.outputs["Combined"], technique="ssss", scene=desc, pixels_per_unit=scale
    )
    assert "Skin: the ssss node group uses its fitted width (x2)" in notes
    assert any(n.startswith("Skin: its fitted gain (1.1, 1, 0.9) is not applied") for n in notes), notes
    assert follow_scene(tree, desc, scale) == []
    moved = follow_scene(tree, desc, {1: SCALE * 1.2, 2: SCALE * 1.01})
    assert len(moved) == 1 and "SSS Lab SSSS Skin" in moved[0] and "set up the compositor again" in moved[0]
