"""Christensen-Burley normalized diffusion gathered along a golden-angle spiral: its function and
``Technique`` spec (``technique.py``, the NumPy reference)."""

from .technique import TECHNIQUE, burley

__all__ = ["TECHNIQUE", "burley"]
