"""Burley's samples that land on something in front of their pixel (docs/references.md §1): the
surface there is hidden, not absent, so such a sample counts its pixel's own light at its pixel's
depth; samples on what lies behind (a farther surface, the background) are dropped and the rest
renormalized. Every call runs on both backends (the autouse fixture of this folder)."""

import numpy as np
import pytest

from sss_lab.core.optics.profiles import TRUNCATION
from sss_lab.core.scene.scene import Camera
from sss_lab.core.techniques.burley.technique import burley

N = 96
#: The columns left of EDGE hold the strip (off the mask unless a test says otherwise).
EDGE = 40
Z = 2.0
ROWS = slice(30, 66)  # away from the top and bottom of the frame


def _run(strip_depth=None, *, strip_in_mask=False, ids=False, light=None):
    """A plane at depth Z facing an orthographic camera (1 px per unit) with a ramp of light
    (its column), Burley with a 48 px footprint (red; green and blue half and a quarter of it),
    1024 samples of the fixed spiral (``adaptive=False``: every pixel the same samples, whatever
    lies beside it); the columns
    left of EDGE at ``strip_depth`` (None: the plane continues there, on the mask)."""
    cam = Camera(type="ORTHO", width_px=N, height_px=N, ortho_scale=float(N))
    x = np.arange(N, dtype=np.float32)
    if light is None:
        light = np.broadcast_to(x[None, :, None], (N, N, 3)).copy()
    depth = np.full((N, N), Z, np.float32)
    mask = np.ones((N, N), bool)
    object_id = np.ones((N, N), np.float32) if ids else None
    if strip_depth is not None:
        depth[:, :EDGE] = strip_depth
        mask[:, :EDGE] = strip_in_mask
        if ids:
            object_id[:, :EDGE] = 2.0
    d = 48.0 / TRUNCATION
    return burley(
        diffuse=light,
        albedo=np.ones_like(light),
        depth=depth,
        mask=mask,
        camera=cam,
        d_su=(d, 0.5 * d, 0.25 * d),
        object_id=object_id,
        n_samples=1024,
        adaptive=False,
        random_rotation=False,
        smooth_px=0,
    )


def test_what_lies_behind_is_dropped_as_the_background_is():
    background = _run(1e10)
    for ids in (False, True):
        np.testing.assert_array_equal(_run(5.0, ids=ids)[:, EDGE:], background[:, EDGE:])


def test_a_hidden_sample_counts_its_pixels_light_whatever_hides_it():
    # Only the order matters (nearer than the pixel): the occluder's depth, and whether it is off
    # the mask or another object on it, change nothing on the plane.
    near = _run(0.5)[:, EDGE:]
    np.testing.assert_array_equal(_run(Z - 0.01)[:, EDGE:], near)
    np.testing.assert_array_equal(_run(0.5, ids=True)[:, EDGE:], near)
    np.testing.assert_array_equal(_run(0.5, strip_in_mask=True, ids=True)[:, EDGE:], near)
    # A uniform light stays uniform: the hidden samples carry the pixel's own.
    flat = _run(0.5, light=np.full((N, N, 3), 0.7, np.float32))[:, EDGE:]
    np.testing.assert_allclose(flat, 0.7, rtol=1e-6)


@pytest.mark.parametrize("channel", (0, 1, 2))
def test_hidden_surface_moves_the_edge_towards_the_unoccluded_plane(channel):
    # On a ramp of light the gather returns about the ramp where the plane is whole. At an
    # occluder's edge, dropping the hidden side leaves the pixel's brighter side alone: the result
    # is biased by the profile's mean reach into that side. With the hidden side counting the
    # pixel's own light the bias is (W_c + W_v) / (W_c + W_h + W_v) of it (W: the weights of the
    # samples on the pixel itself, the visible side and the hidden side), between one half and
    # one: smaller, never of the other sign.
    col = (ROWS, EDGE, channel)
    plane = _run()[col]
    dropped = _run(1e10)[col] - plane
    hidden = _run(0.5)[col] - plane
    assert np.all(dropped > 0.5)  # measured 0.8-3.9 (a column of the ramp is 1), by channel
    assert np.all(hidden > 0)
    assert np.all(hidden < dropped)
    assert np.all(hidden > 0.5 * dropped)
    # Beyond the footprint from the edge, nothing changes.
    far = (ROWS, EDGE + 49, channel)
    np.testing.assert_array_equal(_run(0.5)[far], _run(1e10)[far])
