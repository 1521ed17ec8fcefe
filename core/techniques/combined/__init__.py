"""Diffusion (Burley or SSSS) plus the light from behind through the medium: its function and
``Technique`` spec (``technique.py``, the NumPy reference)."""

from .technique import TECHNIQUE, combined

__all__ = ["TECHNIQUE", "combined"]
