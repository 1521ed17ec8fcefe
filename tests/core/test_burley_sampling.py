"""Burley's default sampling: a spiral turned per pixel plus a 3 x 3 same-surface clean-up, chosen
on the fidelity suite (benchmarks/fidelity) because the fixed spiral draws ghost copies of
shadow edges ("streaks", "stepping") at large footprints. Here: no banding from 10 to 150 px."""

import numpy as np
import pytest

from sss_lab.core.optics.profiles import TRUNCATION
from sss_lab.core.scene.scene import Camera
from sss_lab.core.techniques.burley.technique import burley

N = 128


def _edge(footprint_px, **kw):
    """A flat white surface under an orthographic camera (1 px per unit), lit on one side of a
    slanted straight edge; Burley with a footprint (16 d, red; green and blue narrower) of
    ``footprint_px``. Returns the image and each pixel's signed distance to the edge in px."""
    cam = Camera(type="ORTHO", width_px=N, height_px=N, ortho_scale=float(N))
    d = footprint_px / TRUNCATION
    yy, xx = np.mgrid[0:N, 0:N]
    dist = ((xx - N / 2) + 0.3 * (yy - N / 2)) / np.hypot(1.0, 0.3)
    light = np.zeros((N, N, 3), np.float32)
    light[dist < 0] = 1.0
    out = burley(
        diffuse=light,
        albedo=np.ones_like(light),
        depth=np.ones((N, N), np.float32),
        mask=np.ones((N, N), bool),
        camera=cam,
        d_su=(d, 0.6 * d, 0.3 * d),
        **kw,
    )
    return out, dist


@pytest.mark.parametrize("footprint_px", (10, 30, 90, 150))
def test_default_sampling_has_no_banding_along_edges(footprint_px):
    truth, dist = _edge(footprint_px, n_samples=1024, smooth_px=0)
    inner = (slice(N // 4, 3 * N // 4),) * 2
    lines = np.round(dist[inner]).astype(int)

    def banding_and_rms(image):
        # Banding: the error that repeats all along the edge, i.e. the mean error of each line
        # parallel to it (noise averages out there, streaks do not).
        err = (image - truth)[inner]
        band = np.sqrt(np.mean([np.mean(err[lines == k], axis=0) ** 2 for k in np.unique(lines)]))
        return band, np.sqrt(np.mean(err**2))

    fixed_band, fixed_rms = banding_and_rms(_edge(footprint_px, random_rotation=False, smooth_px=0)[0])
    band, rms = banding_and_rms(_edge(footprint_px)[0])
    # Measured: banding 0.0006 / 0.0011 / 0.0028 / 0.0034 against the fixed spiral's 0.0039 /
    # 0.0072 / 0.0118 / 0.0167 (lit level 1); 0.35 of it leaves room for another seed's noise.
    assert band <= 0.35 * fixed_band, (band, fixed_band)
    if footprint_px >= 90:
        # Where the clean-up applies, the whole error is smaller too (measured 0.0103 vs 0.0166 and
        # 0.0085 vs 0.0213); below it the rotation's noise costs at most 20 % (0.0066 vs 0.0056).
        assert rms < fixed_rms
    else:
        assert rms < 1.25 * fixed_rms
