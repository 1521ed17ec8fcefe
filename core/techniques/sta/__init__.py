"""Simple translucency (STA): back-lighting times a baked thickness map: its function and
``Technique`` spec (``technique.py``, the NumPy reference)."""

from .technique import TECHNIQUE, sta

__all__ = ["TECHNIQUE", "sta"]
