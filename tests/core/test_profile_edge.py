"""The shadow-edge benchmark's Burley curve (``benchmarks/profile_edge.py``) against the same
quantity computed another way."""

import numpy as np
import pytest

from benchmarks.profile_edge import burley_edge
from sss_lab.core.optics.profiles import burley_radial_pdf


def _polar(x: float, d: float) -> float:
    # Light at distance |x| into the shadow of a half-plane lit beyond the edge: the share of the
    # profile's radii r > |x| whose direction reaches across, arccos(|x| / r) / pi, over the radial
    # pdf (polar coordinates, core.optics.profiles; the benchmark integrates the 1-D marginal instead).
    a = abs(x)
    s = np.linspace(0.0, 12.0, 400001)  # r = a cosh(s): smooth where arccos(a / r) has its root
    r = a * np.cosh(s)
    f = burley_radial_pdf(r, d) * np.arccos(np.minimum(a / r, 1.0)) / np.pi * a * np.sinh(s)
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(s)))


@pytest.mark.parametrize("x", [-0.2, -1.0, -3.0, -9.0])
def test_the_edge_curve_is_the_profiles_share_across_the_edge(x):
    d = 1.7
    expected = _polar(x * d, d)
    # The curve's table is accurate to about 1e-4 of the lit level (its total reads 0.49994 for
    # 0.5): the midpoint rule over the marginal's log singularity.
    assert burley_edge(np.array([x * d]), d)[0] == pytest.approx(expected, abs=2e-4)


def test_the_edge_curve_refuses_what_its_table_cannot_hold():
    with pytest.raises(ValueError, match="beyond the table"):
        burley_edge(np.array([-1.0]), 1e-3)
