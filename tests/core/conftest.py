"""Every core test runs the techniques on both backends: in ``core.compute.backend``'s check mode each
call of STA, SSSS and Burley computes the NumPy reference and the compiled kernel and fails
(``BackendMismatch``) where they differ beyond the float32 bound of ``core.compute.backend.tolerance``;
the tests then check the compiled result."""

import pytest

from sss_lab.core.compute import backend


@pytest.fixture(autouse=True)
def _both_backends():
    with backend.use("check"):
        yield
