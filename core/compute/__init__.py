"""How kernels run: the backend switch (compiled, NumPy, check) and the Numba kernels."""
