"""Simple translucency approximation (STA), in NumPy.

Barre-Brisebois & Bouchard, "Approximating Translucency for a Fast, Cheap and Convincing
Subsurface Scattering Look", GDC 2011 / GPU Pro 2 (REFERENCES.md section 4). Per light:

    L_T   = normalize(L + d_T N)                 (the seed deck and three.js normalize it)
    T_dir = s_T max(0, V . -L_T)^p_T
    T     = A_L t (T_dir + a_T)
    added = albedo x light colour x (E_L / pi) x T

L points from the surface to the light, V from the surface to the viewer, N is the shading
normal, t the local thickness map in the translucency convention (1 = thin; a map in the
thickness convention is read as 1 - t). A_L is the light's attenuation and E_L its irradiance
at the point in Blender's units: a sun gives its Strength (W/m^2); a point or spot light of
power P at distance r gives P / (4 pi r^2), a spot times Cycles' smoothstep cone falloff
(spot_size, spot_blend); an area light of power P gives P cos(theta_L) / (pi r^2). The 1 / pi
is a Lambertian surface's, so that s_T = 1 makes the translucency as bright as a diffuse surface
facing the light; the original leaves the scale to the artist.

Extremes, each tested: when L + d_T N vanishes the direction is undefined and that light adds
nothing there; p_T = 0 gives s_T wherever V . -L_T > 0 (and nothing where it is <= 0); large p_T
(e.g. 128) narrows the lobe without overflow; thickness 0 adds nothing, 1 the full term.
"""

from __future__ import annotations

import math

import numpy as np

from . import _arrays
from .scene import Camera, Light

THICKNESS_CONVENTIONS = ("translucency", "thickness")

_EPS = np.float32(1e-6)


def _norm(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    length = np.sqrt((v * v).sum(axis=-1, keepdims=True))
    return v / np.maximum(length, np.float32(1e-30)), length[..., 0]


def _smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / max(e1 - e0, 1e-30), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def light_at(light: Light, position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit vectors towards the light (N, 3), irradiance E_L (N,)) at world positions (N, 3)."""
    if light.type == "SUN":
        to_light = np.broadcast_to((-light.direction).astype(np.float32), position.shape)
        return to_light, np.full(position.shape[0], light.energy, np.float32)
    delta = light.position.astype(np.float32) - position
    to_light, dist = _norm(delta)
    r2 = np.maximum(dist * dist, np.float32(1e-12))
    if light.type == "AREA":
        cos_l = np.maximum((-to_light) @ light.direction.astype(np.float32), 0.0)
        return to_light, (light.energy * cos_l / (math.pi * r2)).astype(np.float32)
    e = light.energy / (4.0 * math.pi * r2)
    if light.type == "SPOT":
        # Cycles' spot attenuation: zero outside the cone, smoothstep over the blend region.
        cos_angle = (-to_light) @ light.direction.astype(np.float32)
        half = math.cos(light.spot_size / 2.0)
        smooth = (1.0 - half) * light.spot_blend
        t = cos_angle - half
        cone = np.where(t > 0, 1.0, 0.0)
        if smooth > 0:
            cone = cone * _smoothstep(0.0, smooth, t)
        e = e * cone
    return to_light, e.astype(np.float32)


def sta(
    *,
    albedo,
    normal,
    position,
    thickness,
    mask,
    camera: Camera,
    lights,
    distortion: float = 0.1,
    power: float = 2.0,
    scale: float = 1.0,
    ambient: float = 0.0,
    thickness_convention: str = "translucency",
) -> np.ndarray:
    """The translucency term STA adds, float32 (H, W, 3); zero outside ``mask``.

    ``albedo`` (H, W, 3) Diffuse Color; ``normal`` (H, W, 3) world-space normals; ``position``
    (H, W, 3) world positions; ``thickness`` (H, W) in [0, 1]; ``lights``: core.scene.Light list.
    ``distortion`` d_T, ``power`` p_T, ``scale`` s_T, ``ambient`` a_T as in the paper.
    STA adds light (it models light arriving from behind, not redistributed light): its sum is
    not conserved, by design. Pixels with non-finite inputs get 0.
    """
    if not isinstance(camera, Camera):
        raise ValueError(f"camera: expected a core.scene.Camera, got {type(camera).__name__}")
    if thickness_convention not in THICKNESS_CONVENTIONS:
        raise ValueError(
            f"thickness_convention: {thickness_convention!r} is not one of {', '.join(THICKNESS_CONVENTIONS)}"
        )
    for light in lights:
        if not isinstance(light, Light):
            raise ValueError(f"lights: expected core.scene.Light entries, got {type(light).__name__}")
    try:
        distortion = float(distortion)
    except (TypeError, ValueError):
        raise ValueError(f"distortion: expected a number, got {distortion!r}") from None
    if not math.isfinite(distortion):
        raise ValueError(f"distortion: expected a finite number, got {distortion!r}")
    power = _arrays.positive_finite(power, "power")
    scale = _arrays.positive_finite(scale, "scale")
    ambient = _arrays.positive_finite(ambient, "ambient")
    a = _arrays.image(albedo, "albedo")
    shape = a.shape[:2]
    n = _arrays.image(normal, "normal")
    p = _arrays.image(position, "position")
    t = _arrays.image(thickness, "thickness", None)
    _arrays.same_size(shape, normal=n, position=p, thickness=t)
    m = _arrays.mask_array(mask, shape) & _arrays.finite_pixels(a, n, p, t)
    out = np.zeros(a.shape, np.float32)
    if not m.any() or not lights:
        return out
    tt = np.clip(t[m], 0.0, 1.0)
    if thickness_convention == "thickness":
        tt = 1.0 - tt
    nn, _ = _norm(n[m])
    pp = p[m]
    view = camera.view_vectors(pp[None])[0]
    total = np.zeros((pp.shape[0], 3), np.float32)
    for light in lights:
        if light.energy == 0:
            continue
        to_light, irradiance = light_at(light, pp)
        lt, length = _norm(to_light + np.float32(distortion) * nn)
        vdot = -(view * lt).sum(axis=1)
        lobe = np.where(vdot > 0, np.maximum(vdot, 0.0) ** np.float32(power), 0.0)
        t_dir = np.float32(scale) * lobe
        t_dir = np.where(length > _EPS, t_dir, 0.0)  # L + d_T N vanished: no direction, no light
        term = irradiance / np.float32(math.pi) * tt * (t_dir + np.float32(ambient))
        total += term[:, None] * np.asarray(light.color, np.float32)[None, :]
    out[m] = a[m] * total
    return out
