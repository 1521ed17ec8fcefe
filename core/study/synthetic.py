"""Synthetic render passes of an analytic scene, for tests and benchmarks without Blender.

A perspective camera at the origin looks down -Z (identity ``matrix_world``) at a plane at
z = -6 and two spheres; two sun lights (a key light from the front left, a back light). The
passes follow Cycles' conventions (docs/references.md §2): Depth is planar view z with 1e10
on the background, Object and Material Index are 0 there, Diffuse Direct/Indirect exclude the
BSDF colour and Diffuse Color holds it, Combined = Diffuse Color x (Direct + Indirect) + a
constant glossy term, alpha 1 on geometry and 0 on the background. Rows run top to bottom.
The light is shadowless and computed in float64, then stored as float32.
"""

from __future__ import annotations

import numpy as np

from ..scene.scene import Camera, Light, MaterialSSS, SceneDescription

#: (name, material pass index, object pass index, centre, radius) of the two spheres.
SPHERES = (
    ("Skin", 2, 2, (-0.4, -0.1, -4.0), 1.1),
    ("Wax", 3, 3, (1.25, 0.55, -3.6), 0.45),
)
PLANE_Z = -6.0
PLANE_HALF_WIDTH = 2.4  # beyond |x| > this, background
GLOSSY = 0.05  # constant non-diffuse light added to Combined on geometry
INDIRECT = 0.1  # constant diffuse indirect light
BACKGROUND = (0.05, 0.06, 0.08)

DEFAULT_MATERIALS = (
    MaterialSSS(index=1, name="Plaster", base_color=(0.7, 0.7, 0.7), subsurface_weight=0.0),
    MaterialSSS(
        index=2,
        name="Skin",
        method="BURLEY",
        base_color=(0.8, 0.5, 0.4),
        subsurface_weight=1.0,
        subsurface_radius=(1.0, 0.2, 0.1),
        subsurface_scale=0.3,
    ),
    MaterialSSS(
        index=3,
        name="Wax",
        method="RANDOM_WALK",
        base_color=(0.9, 0.8, 0.5),
        subsurface_weight=1.0,
        subsurface_radius=(1.0, 0.8, 0.5),
        subsurface_scale=0.2,
    ),
)


def _sun(name: str, direction, strength: float) -> Light:
    """A sun shining along ``direction`` (its local -Z), as a row-major matrix_world."""
    z = -np.asarray(direction, dtype=np.float64)
    z /= np.linalg.norm(z)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = x, y, z
    m[:3, 3] = -4.0 * z  # position does not matter for a sun
    return Light(type="SUN", name=name, energy=strength, matrix_world=tuple(m.ravel()))


LIGHTS = (
    _sun("Key", (0.5, -0.4, -0.75), 3.0),  # from the front left, towards -Z
    _sun("Back", (-0.2, 0.1, 1.0), 2.0),  # from behind the spheres, towards the camera
)


def sphere_scene(
    width: int = 48,
    height: int = 32,
    *,
    materials: tuple[MaterialSSS, ...] = DEFAULT_MATERIALS,
    lens_mm: float = 35.0,
) -> tuple[dict[str, np.ndarray], SceneDescription]:
    """(passes by Blender 5.x name, scene description) of the plane-and-spheres scene.

    Passes: Combined (H, W, 4); Depth, Object Index, Material Index, Thickness (H, W);
    Normal, Position, Diffuse Direct, Diffuse Indirect, Diffuse Color (H, W, 3). Thickness is
    a translucency-convention map (1 = thin): 1 - |n . view| on the spheres, 0 on the plane.
    Materials are looked up by their pass index (1 plane, 2 and 3 the spheres); an index with
    no entry in ``materials`` is shaded mid grey.
    """
    camera = Camera(type="PERSP", width_px=width, height_px=height, lens_mm=lens_mm, sensor_width_mm=36.0)
    f = camera.focal_px
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    # Row 0 is the top of the picture (+Y in camera space).
    d = np.stack([(xs + 0.5 - width / 2) / f, -(ys + 0.5 - height / 2) / f, -np.ones_like(xs)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)

    t_best = np.full((height, width), np.inf)
    normal = np.zeros((height, width, 3))
    mat_index = np.zeros((height, width))
    obj_index = np.zeros((height, width))
    # The plane z = PLANE_Z facing the camera.
    t_plane = PLANE_Z / d[..., 2]
    hit_plane = (t_plane > 0) & (np.abs(t_plane * d[..., 0]) <= PLANE_HALF_WIDTH)
    t_best[hit_plane] = t_plane[hit_plane]
    normal[hit_plane] = (0.0, 0.0, 1.0)
    mat_index[hit_plane] = 1
    obj_index[hit_plane] = 1
    for _, m_index, o_index, centre, radius in SPHERES:
        c = np.asarray(centre)
        b = d @ c  # ray origin at 0: |t d - c|^2 = r^2 -> t^2 - 2 b t + |c|^2 - r^2 = 0
        disc = b * b - (c @ c - radius * radius)
        ok = disc >= 0
        t = np.where(ok, b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
        closer = ok & (t > 0) & (t < t_best)
        t_best[closer] = t[closer]
        p = t[closer, None] * d[closer]
        normal[closer] = (p - c) / radius
        mat_index[closer] = m_index
        obj_index[closer] = o_index
    geometry = np.isfinite(t_best)
    position = np.where(geometry[..., None], np.where(np.isfinite(t_best), t_best, 0.0)[..., None] * d, 0.0)
    depth = np.where(geometry, -position[..., 2], 1e10)

    albedo = np.zeros((height, width, 3))
    by_index = {m.index: m for m in materials}
    for index in np.unique(mat_index[geometry]):
        m = by_index.get(int(index))
        albedo[mat_index == index] = m.base_color if m is not None else (0.5, 0.5, 0.5)
    direct = np.zeros((height, width, 3))
    for light in LIGHTS:
        towards = -light.direction
        direct += (np.maximum(normal @ towards, 0.0) * light.energy)[..., None] * np.asarray(light.color)
    direct[~geometry] = 0.0
    indirect = np.where(geometry[..., None], INDIRECT, 0.0) * np.ones(3)
    combined = np.zeros((height, width, 4))
    combined[..., :3] = albedo * (direct + indirect) + np.where(geometry[..., None], GLOSSY, 0.0)
    combined[~geometry, :3] = BACKGROUND
    combined[..., 3] = geometry
    view = -d
    on_sphere = mat_index >= 2
    thickness = np.where(on_sphere, 1.0 - np.abs(np.sum(normal * view, axis=-1)), 0.0)

    passes = {
        "Combined": combined,
        "Depth": depth,
        "Normal": normal,
        "Position": position,
        "Object Index": obj_index,
        "Material Index": mat_index,
        "Diffuse Direct": direct,
        "Diffuse Indirect": indirect,
        "Diffuse Color": albedo,
        "Thickness": thickness,
    }
    passes = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in passes.items()}
    scene = SceneDescription(camera=camera, lights=LIGHTS, materials=tuple(materials), meta={"source": "synthetic"})
    return passes, scene


def write_scene(path: str, passes: dict[str, np.ndarray], scene: SceneDescription, *, view_layer="ViewLayer") -> str:
    """Write ``passes`` as a Blender 5.2-style multilayer EXR and the scene JSON beside it."""
    import os

    from ..scene.exr import write_layers

    write_layers(path, {f"{view_layer}.{name}": arr for name, arr in passes.items()})
    stem, _ = os.path.splitext(path)
    with open(stem + ".json", "w", encoding="utf-8") as fh:
        fh.write(scene.to_json())
    return path
