"""PNG output for previews, error maps and report grids, with the standard library only.

8-bit RGB, no interlace, one IDAT chunk (zlib level 6). Display images go through
``metrics.tonemap``; error maps through ``heat``.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

from ..base.files import write_bytes
from .metrics import tonemap


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png(rgb8: np.ndarray) -> bytes:
    """PNG bytes of a uint8 (H, W, 3) image, rows top to bottom."""
    img = np.asarray(rgb8)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"encode_png: expected a uint8 (H, W, 3) array, got {img.dtype} {img.shape}")
    h, w = img.shape[:2]
    raw = np.concatenate([np.zeros((h, 1), dtype=np.uint8), img.reshape(h, w * 3)], axis=1).tobytes()
    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(raw, 6)) + _chunk(b"IEND", b"")
    )


def encode_png16_gray(values: np.ndarray) -> bytes:
    """PNG bytes of a single-channel image at 16 bits: ``values`` float (H, W) in 0..1, rows top to
    bottom, written linearly (0 -> 0, 1 -> 65535, rounded); values outside 0..1 are refused."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.shape[0] < 1 or v.shape[1] < 1:
        raise ValueError(f"encode_png16_gray: expected a (H, W) array, got shape {v.shape}")
    if not np.all(np.isfinite(v)) or v.min() < 0 or v.max() > 1:
        raise ValueError("encode_png16_gray: expected finite values in 0..1")
    h, w = v.shape
    rows = np.round(v * 65535.0).astype(">u2").view(np.uint8).reshape(h, 2 * w)
    raw = np.concatenate([np.zeros((h, 1), dtype=np.uint8), rows], axis=1).tobytes()
    header = struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(raw, 6)) + _chunk(b"IEND", b"")
    )


def to_display(linear: np.ndarray, *, exposure: float = 1.0) -> np.ndarray:
    """Linear scene-referred RGB(A) to 8-bit display RGB (tone mapped, NaN shown as magenta)."""
    x = np.asarray(linear, dtype=np.float64)[..., :3] * exposure
    bad = ~np.isfinite(x).all(axis=-1)
    out = np.round(tonemap(np.nan_to_num(x, nan=0.0, posinf=0.0, neginf=0.0)) * 255.0).astype(np.uint8)
    out[bad] = (255, 0, 255)
    return out


def heat(values: np.ndarray, *, vmax: float) -> np.ndarray:
    """A black-red-yellow-white ramp of ``values`` in [0, vmax] as 8-bit RGB."""
    t = np.clip(np.nan_to_num(np.asarray(values, dtype=np.float64) / max(vmax, 1e-30)), 0.0, 1.0)
    r = np.clip(3.0 * t, 0, 1)
    g = np.clip(3.0 * t - 1.0, 0, 1)
    b = np.clip(3.0 * t - 2.0, 0, 1)
    return np.round(np.stack([r, g, b], axis=-1) * 255.0).astype(np.uint8)


def write_png(path: str, rgb8: np.ndarray) -> str:
    """Write atomically (temp file in the same folder, then rename)."""
    write_bytes(path, encode_png(rgb8))
    return path


def grid(tiles: list[np.ndarray], *, columns: int, gap: int = 2) -> np.ndarray:
    """Tile uint8 (H, W, 3) images of one size into a grid with ``gap`` dark pixels between."""
    if not tiles:
        raise ValueError("grid: no tiles")
    h, w = tiles[0].shape[:2]
    if any(t.shape != (h, w, 3) for t in tiles):
        raise ValueError(f"grid: every tile must be ({h}, {w}, 3)")
    rows = -(-len(tiles) // columns)
    out = np.full((rows * h + (rows - 1) * gap, columns * w + (columns - 1) * gap, 3), 24, dtype=np.uint8)
    for i, t in enumerate(tiles):
        r, c = divmod(i, columns)
        out[r * (h + gap) : r * (h + gap) + h, c * (w + gap) : c * (w + gap) + w] = t
    return out
