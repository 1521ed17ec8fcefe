"""core/fidelity.py: the slide deck's fidelity table, measured; checked against the profile's
own closed-form line spread (``analytic_row``)."""

import numpy as np
import pytest

from sss_lab.core import fidelity, kernels
from sss_lab.core.scene import MaterialSSS


@pytest.mark.parametrize("radius", ((1.0, 0.2, 0.1), (1.0, 0.7, 0.5)))
def test_diffusion_techniques_reproduce_the_profiles_line_spread(radius):
    material = MaterialSSS(
        index=1, name="skin", base_color=(0.8, 0.5, 0.4), subsurface_radius=radius, subsurface_scale=0.01
    )
    table = fidelity.fidelity_table(material)
    rows = table["rows"]
    analytic = rows["Burley profile (analytic)"]
    d_max = max(fidelity._mapping.burley_d(material))
    pixel = 16 * d_max / (fidelity._KERNEL_SHARE * fidelity._HALF)  # scene units per pixel of the test
    offsets = kernels.preintegrated_kernel(17, d_su=fidelity._mapping.burley_d(material)).offsets_su
    for name in ("SSSS", "Burley"):
        row = rows[name]
        for c in range(3):
            # r90 is read off whole pixels, and the profile's own r90 falls between them; 1.5 px
            # covers that rounding plus the half pixel of the sample positions. SSSS puts each
            # footprint's light at its tap: it may also be off by half the gap between the taps
            # around the r90 (17 taps, quadratic spacing).
            tol = 1.5 * pixel
            if name == "SSSS":
                r = analytic["r90_su"][c]
                i = int(np.searchsorted(offsets, r))
                tol += 0.5 * (offsets[min(i, len(offsets) - 1)] - offsets[max(i - 1, 0)])
            assert abs(row["r90_su"][c] - analytic["r90_su"][c]) <= tol, (name, c, row, analytic)
        assert all(abs(e - 1) < 0.005 for e in row["energy_ratio"])  # the 0.5 %
    sta = rows["STA"]
    assert sta["r90_su"] == [0.0, 0.0, 0.0]  # local: it does not move the line's light
    assert all(e > 1 for e in sta["energy_ratio"])  # it adds light
    assert table["definition"] == fidelity.DEFINITION
