"""Lights at a point: the direction towards each light and its irradiance there, as the
techniques and the energy model read them (docs/references.md §4: a sun's Strength, a point or spot
light's power over 4 pi r^2 with Cycles' cone falloff, an area light's P cos / (pi r^2))."""

from __future__ import annotations

import math

import numpy as np

from ..scene.scene import Light

#: How a thickness map is read: 1 = thin ("translucency", the convention STA uses) or 1 = thick.
THICKNESS_CONVENTIONS = ("translucency", "thickness")


def norm(x, y, z):
    """Normalize planar vectors (rows x, y, z); returns (x, y, z, length)."""
    length = x * x
    length += y * y
    length += z * z
    np.sqrt(length, out=length)
    inv = np.maximum(length, np.float32(1e-30))
    np.divide(np.float32(1.0), inv, out=inv)
    return x * inv, y * inv, z * inv, length


def _smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / np.float32(max(e1 - e0, 1e-30)), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def light_at(light: Light, px, py, pz):
    """(unit vector towards the light as planar rows lx, ly, lz; irradiance E_L) at world
    positions given as planar rows (px, py, pz). A sun gives float32 scalars (the same everywhere)."""
    f32 = np.float32
    if light.type == "SUN":
        d = (-light.direction).astype(f32)
        return d[0], d[1], d[2], f32(light.energy)
    c = light.position.astype(f32)
    lx, ly, lz, dist = norm(c[0] - px, c[1] - py, c[2] - pz)
    r2 = np.maximum(dist * dist, f32(1e-12))
    if light.type == "AREA":
        a = light.direction.astype(f32)
        cos_l = np.maximum(-(lx * a[0] + ly * a[1] + lz * a[2]), 0.0)
        return lx, ly, lz, (f32(light.energy / math.pi) * cos_l / r2).astype(f32)
    e = f32(light.energy / (4.0 * math.pi)) / r2
    if light.type == "SPOT":
        # Cycles' spot attenuation: zero outside the cone, smoothstep over the blend region.
        a = light.direction.astype(f32)
        cos_angle = -(lx * a[0] + ly * a[1] + lz * a[2])
        half = math.cos(light.spot_size / 2.0)
        smooth = (1.0 - half) * light.spot_blend
        t = cos_angle - f32(half)
        cone = (t > 0).astype(f32)
        if smooth > 0:
            cone = cone * _smoothstep(0.0, smooth, t)
        e = e * cone
    return lx, ly, lz, e.astype(f32)
