"""Measuring against Cycles: metrics, sweeps, the fit, the fidelity table, references, reports and
their pictures, the kernels' warm-up."""
