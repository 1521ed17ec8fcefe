"""SSSS weighted by the surface its taps cover (core/techniques/ssss/technique.py, ``weighting="surface"``): equal
surfaces give the paper's filter to the bit, and each pass is the filter of surface x light over
the filter of the surface (the change of variables from pixels to surface)."""

import math

import numpy as np
import pytest

from sss_lab.core.compute import backend
from sss_lab.core.optics import kernels
from sss_lab.core.optics.surface import surface_area
from sss_lab.core.scene.scene import Camera
from sss_lab.core.techniques.ssss.technique import MAX_SURFACE, ssss

D_SU = (0.01, 0.005, 0.0025)


def _both(fn):
    """``fn()`` on the NumPy reference and on the compiled kernels."""
    out = []
    for name in ("numpy", "numba"):
        with backend.use(name):
            out.append(fn())
    return out


@pytest.mark.parametrize("case", ["facing", "tilted"])
def test_equal_surfaces_give_the_papers_filter_to_the_bit(case):
    rng = np.random.default_rng(3)
    h, w = 40, 64
    light = (rng.random((h, w, 3)) + 0.1).astype(np.float32)
    albedo = np.full((h, w, 3), 0.8, np.float32)
    mask = np.ones((h, w), bool)
    mask[:6, :10] = False  # taps that land off the mask give their weight to the centre
    if case == "facing":
        # Planes facing an orthographic camera, with a step (follow surface blends across it).
        camera = Camera(type="ORTHO", width_px=w, height_px=h, ortho_scale=1.0)
        z = np.full((h, w), 3.0, np.float32)
        z[:, 40:] = 3.02
        d_su = (0.004, 0.002, 0.001)
    else:
        # A plane tilted about the vertical axis under an orthographic camera, its depth steps
        # exact in float32: every pixel covers the same surface, 1 / cos = sqrt(1 + 0.5^2).
        camera = Camera(type="ORTHO", width_px=w, height_px=h, ortho_scale=float(w))  # 1 px per unit
        z = np.broadcast_to(4.0 + 0.5 * np.arange(w, dtype=np.float32), (h, w)).copy()
        d_su = (0.4, 0.2, 0.1)
    area = surface_area(z, mask, camera)
    assert np.unique(area[mask]).size == 1  # the premise: equal surfaces
    if case == "tilted":
        assert area[mask][0] == pytest.approx(math.sqrt(1.25), rel=1e-6)

    def run(weighting):
        args = {"diffuse": light, "albedo": albedo, "depth": z, "mask": mask, "camera": camera}
        return ssss(**args, d_su=d_su, energy="lambert", weighting=weighting)

    for screen, surface in zip(_both(lambda: run("screen")), _both(lambda: run("surface")), strict=True):
        assert not np.array_equal(screen, albedo * light)  # the filter did spread the light
        np.testing.assert_array_equal(surface, screen)


def test_each_pass_filters_surface_times_light_over_the_surface():
    # A cylinder along the image's columns under an orthographic camera (64 px per unit): depth
    # varies along rows only, so each row's pixels cover from 1 (its axis) to about 2.4 times
    # (its sides, capped at MAX_SURFACE) the surface of a pixel facing the camera, and every row
    # is the same. The column pass then averages equal values and the result is the row pass's:
    # wsum x sum_k w_k (A E)(x + s o_k) / sum_k w_k A(x + s o_k), linear interpolation along the
    # row, clipped at its ends, without follow surface (so the row's depths do not matter).
    h, w = 24, 64
    camera = Camera(type="ORTHO", width_px=w, height_px=h, ortho_scale=1.0)
    px = camera.ortho_px_per_unit
    xs = (np.arange(w) + 0.5 - w / 2) / px
    z_row = (3.0 - np.sqrt(0.55**2 - xs**2)).astype(np.float32)
    z = np.broadcast_to(z_row, (h, w)).copy()
    rng = np.random.default_rng(5)
    e_row = (rng.random((w, 3)) * np.linspace(0.2, 2.0, w)[:, None]).astype(np.float32)
    light = np.broadcast_to(e_row, (h, w, 3)).copy()
    albedo = np.ones((h, w, 3), np.float32)
    mask = np.ones((h, w), bool)
    area = np.minimum(surface_area(z, mask, camera)[h // 2], np.float32(MAX_SURFACE)).astype(np.float64)
    assert area.min() == 1.0 and area.max() == MAX_SURFACE  # the premise: unequal surfaces, the cap reached

    kernel = kernels.make_kernel("preintegrated", 17, d_su=D_SU)
    offsets_px = kernel.offsets_su * px
    assert 5.0 < offsets_px.max() < w / 4  # taps span several pixels
    pos = np.clip(np.arange(w)[:, None] + offsets_px[None, :], 0, w - 1)
    expected = np.empty((w, 3))
    for c in range(3):
        num = np.interp(pos, np.arange(w), area * e_row[:, c]) @ kernel.weights[:, c]
        den = np.interp(pos, np.arange(w), area) @ kernel.weights[:, c]
        expected[:, c] = kernel.weights[:, c].sum() * num / den
    unweighted = np.empty((w, 3))
    for c in range(3):
        unweighted[:, c] = np.interp(pos, np.arange(w), e_row[:, c].astype(np.float64)) @ kernel.weights[:, c]
    assert np.abs(expected - unweighted).max() > 0.01  # the weighting changes the result (bound: ~2e-5)

    def run():
        args = {"diffuse": light, "albedo": albedo, "depth": z, "mask": mask, "camera": camera}
        return ssss(**args, kernel=kernel, follow_surface=False, energy="lambert")

    # The float32 bound of core.compute.backend.tolerance for two float32 results of these sums (one of
    # them here is float64: within it).
    bound = backend.tolerance(2 * (2 * len(kernel) + 1), np.abs(e_row).max())
    for out in _both(run):
        for y in (0, h // 2, h - 1):
            np.testing.assert_allclose(out[y], expected, rtol=0, atol=float(bound))
