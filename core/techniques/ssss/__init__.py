"""Separable subsurface scattering (SSSS): two 1-D per-channel convolutions: its function and
``Technique`` spec (``technique.py``, the NumPy reference)."""

from .technique import TECHNIQUE, ssss

__all__ = ["TECHNIQUE", "ssss"]
