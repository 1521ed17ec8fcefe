"""The medium light crosses from behind: a material's subsurface method, Base Color, IOR and
anisotropy (``Medium``), and the per-channel transmittance through a slab of it, by Burley's law,
Christensen-Burley's disk probes or the random walk's tables (``core/optics/transmittance.py``,
docs/references.md §4 and §14). STA's "medium" falloff and the combined technique's light from
behind both read it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base import arrays
from ..scene.scene import SUBSURFACE_METHODS
from .transmittance import disk_transmittance_rgb, transmittance_rgb


def slab_thickness(translucency: np.ndarray, distance_su: float) -> np.ndarray:
    """Slab thickness (scene units) that a baked translucency value t stands for: D sqrt(1 - t)
    (the bake's AO of a slab of thickness x < D is (x / D)^2, ``core/scene/thickness.py``)."""
    t = np.clip(np.asarray(translucency, np.float32), np.float32(0.0), np.float32(1.0))
    return np.float32(distance_su) * np.sqrt(np.float32(1.0) - t)


def burley_transmittance_rgb(x_su: np.ndarray, d_su) -> np.ndarray:
    """Per-channel Burley transmittance (..., 3), float32, through thickness ``x_su`` (...):
    T_c = (e^{-x/d_c} + 3 e^{-x/(3 d_c)}) / 4 (docs/references.md §4); T_c(0) = 1. A channel
    with d_c = 0 passes light only where x = 0."""
    d = arrays.rgb_lengths(d_su, "transmission_d_su")
    x = np.asarray(x_su, np.float32)
    out = np.empty(x.shape + (3,), np.float32)
    for c in range(3):
        if d[c] > 0:
            e3 = np.exp(-x / np.float32(3.0 * d[c]))
            out[..., c] = np.float32(0.25) * (e3 * e3 * e3 + np.float32(3.0) * e3)
        else:
            out[..., c] = (x == 0).astype(np.float32)
    return out


@dataclass(frozen=True)
class Medium:
    """What the light from behind needs to know of a material's random walk (``core/optics/transmittance.py``):
    its subsurface method, Base Color, the IOR its camera paths refract through and its
    anisotropy. Christensen-Burley ("BURLEY") is not a walk: its disk probes find the far side
    (``core.optics.transmittance.disk_table``, module docstring)."""

    method: str = "RANDOM_WALK"
    base_color: tuple = (0.8, 0.8, 0.8)
    ior: float = 1.4
    anisotropy: float = 0.0

    def __post_init__(self):
        if self.method not in SUBSURFACE_METHODS:
            raise ValueError(f"subsurface_method: {self.method!r} is not one of {', '.join(SUBSURFACE_METHODS)}")
        color = np.asarray(self.base_color, np.float64)
        if color.shape != (3,) or not np.all(np.isfinite(color)):
            raise ValueError(f"base_color: expected three finite numbers (R, G, B), got {self.base_color!r}")

    @property
    def walks(self) -> bool:
        return self.method != "BURLEY"


def medium_of(material) -> Medium:
    """The ``Medium`` of a ``core.scene.scene.MaterialSSS``."""
    m = material
    return Medium(m.method, tuple(m.base_color), float(m.subsurface_ior), float(m.subsurface_anisotropy))


def slab_transmittance_rgb(x_su, length_su, medium: Medium | None, *, view_cos=None) -> np.ndarray:
    """T_c through thickness ``x_su`` (..., 3) float32: Burley's law with d = ``length_su`` when
    ``medium`` is None, Cycles' disk probes' for Christensen-Burley (``core.optics.transmittance.disk_table``),
    else the random walk's (``core.optics.transmittance``, ``length_su`` its mean free path per channel;
    ``view_cos`` the visible normal's cosine to the view)."""
    if medium is None:
        return burley_transmittance_rgb(x_su, length_su)
    if not medium.walks:
        return disk_transmittance_rgb(x_su, length_su)
    return transmittance_rgb(
        x_su,
        length_su,
        medium.base_color,
        view_cos=view_cos,
        ior=medium.ior,
        anisotropy=medium.anisotropy,
        cosine_share=0.5 if medium.method == "RANDOM_WALK_SKIN" else 0.0,
        legacy=medium.method == "RANDOM_WALK_LEGACY",
    )


def exit_weight(albedo, medium: Medium | None, albedo_mode: str = "post") -> np.ndarray | None:
    """Per pixel and channel, what multiplies the transmitted light at the visible surface, or
    None for 1: a random walk divides the closure's weight (the Diffuse Color pass: Base Color x
    the specular layer's share x Subsurface Weight) by Base Color (the walk's albedo does the
    colouring), so the weight is Diffuse Color / Base Color, at most 1; Christensen-Burley keeps
    the closure weight, Diffuse Color itself. ``albedo`` as the technique receives it (the square
    root of Diffuse Color in the "pre-post" albedo mode)."""
    if albedo is None or medium is None:
        return None
    a = arrays.image(albedo, "albedo")
    if arrays.check_albedo_mode(albedo_mode) == "pre-post":
        a = a * a
    if not medium.walks:
        return a
    base = np.asarray(medium.base_color, np.float32)
    w = np.where(base > 0, a / np.maximum(base, np.float32(1e-6)), np.float32(0.0))
    return np.clip(w, 0.0, 1.0).astype(np.float32)
