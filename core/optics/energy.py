"""The light Cycles' subsurface methods return, against a Lambert surface of the same Base Color.

The techniques read passes rendered with Subsurface Weight 0: plain diffuse (Lambert) light.
They redistribute it and keep its energy. Cycles' methods return another amount of light, for
three reasons this module models (docs/references.md §15, §17), each from canonical Cycles renders
(``benchmarks/energy.py``; tables below, in ``benchmarks/results/energy.json``):

1. **The entry** (a convention of the method, the same for every object). In Random Walk,
   Random Walk (Legacy) and Random Walk (Skin) the camera path enters the medium refracted through
   the rough surface (Cycles 5.2 ``kernel/integrator/subsurface.h``, ``subsurface_entry_bounce``)
   and walks until it leaves; where it leaves, a Lambert BSDF of weight 1 gathers the light
   (``subsurface_shader_data_setup``). The single-scattering albedo is inverted from Base Color
   so that a half-space under *diffuse* incidence returns about Base Color; a walk that starts
   along the normal goes deeper and is absorbed more often. So a semi-infinite medium returns
   ``SEMI_INFINITE`` times the Lambert light: a function of the albedo and of the view angle at
   the pixel (through the refraction), not of where the light comes from (the exit is
   Lambertian, as for the passes). Christensen-Burley returns exactly the Lambert light.
   ``entry_gain`` interpolates it per pixel and channel (bilinear in the albedo and the view
   cosine: ``normal_view_cosine`` reads it from the Normal pass where that is rendered, else
   ``view_cosine`` reconstructs it from the Depth pass).
2. **A convex surface** (``convex_gain``). Where the surface curves away from a walk it leaves
   sooner and is absorbed less: spheres of radius R return more light than a flat surface, by
   ``CONVEX`` (per albedo and R in mean free paths; +3-4 % at 32, +7-9 % at 16, +10-18 % at 8 for a
   random walk, measured under a uniform world so that every exit sees the same light), beyond
   what a slab as thick as the sphere's chord gives. ``surface_curvature`` reads the mean
   curvature from the Normal and Position passes, averaged over a mean free path.
3. **A finite object** (``slab_factors``). The visible surface of an object of thickness x (the
   baked thickness map read as a slab, ``core/scene/thickness.py``; where the map finds no far side
   within its distance D, the sphere's chord 2 / curvature, at least D and at most ``CHORD_CAP``
   D) returns ``SLAB_ABOVE`` of the thick object's light: the rest leaves through the far side.
   And light that enters the far side comes through: ``SLAB_BELOW`` of the irradiance there,
   both per albedo and thickness in mean free paths, measured on slabs. The irradiance of the
   surfaces the camera does not see (``unseen_irradiance``) is estimated once per material: each
   lamp's irradiance on the visible normals reversed (the opposite surface of an object symmetric
   about its centre), unshadowed, plus the visible light that the lamps do not explain (a world
   or bounce light, taken to reach the unseen side alike).

The diffusion techniques' ``energy`` parameter chooses. "object" (their default), with the Normal
and Position passes (rendered with the combined technique's passes): the entry's gain as
measured, times the convex gain (faded towards 1 on a shell thinner than its curvature's sphere,
which the slab tables hold), times (their light x f_above + albedo x f_below x E_unseen) where a
thickness map is baked. Without those passes, the entry's gain scaled per material and channel so
that it keeps the passes' total (before the convex gain was modelled, the level of the
semi-infinite entry was off by -5 to +29 % on objects, docs/references.md §15). "view": that
scaled entry alone. "lambert": the passes' light as it is. The constants are the tables; nothing
is fitted to a scene.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base import arrays
from ..compute import backend
from ..scene.scene import Camera


def _kernels():
    """This package's compiled kernels (``_kernels.py``), loaded on first use."""
    return backend.kernels(__package__)


#: Choices of the techniques' ``energy`` parameter (``apply_energy``).
ENERGY_MODES = ("object", "view", "lambert")

#: View angles (degrees from the surface normal) and albedos of ``SEMI_INFINITE``.
VIEW_DEG = (0.0, 20.0, 40.0, 55.0, 65.0, 75.0, 85.0)
ALBEDO = (0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95)

#: Slab thicknesses (mean free paths, ``core.pipeline.mapping.mean_free_path``) and albedos of ``SLAB_ABOVE``
#: and ``SLAB_BELOW``.
SLAB_MFPS = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 128.0)
SLAB_ALBEDO = (0.2, 0.35, 0.5, 0.65, 0.8, 0.92)

#: Sphere radii (mean free paths) of ``CONVEX``'s columns; its rows are the albedos of ``ALBEDO``.
CONVEX_RADII = (64.0, 32.0, 16.0, 8.0, 4.0, 2.0)

#: The longest chord given to a pixel whose thickness map finds no far side within the bake's
#: distance D, in D: the side of a cube whose diagonal is 4 D (the bake's automatic D is a quarter
#: of the object's bounding-box diagonal, ``core.scene.thickness.auto_distance_su``).
CHORD_CAP = 4.0 / 3.0**0.5

#: The widest square (half-width, px) the curvature is averaged over (``apply_energy``).
CURVATURE_REACH_PX = 32

#: Method -> rows per albedo of ``SLAB_ALBEDO``, columns per thickness of ``SLAB_MFPS``: a slab's
#: top face seen straight on, lit straight from above (``SLAB_ABOVE``) or from below
#: (``SLAB_BELOW``), over a Lambert top face lit from above; 64 samples. ``SEMI_INFINITE``: method ->
#: rows per view angle of ``VIEW_DEG``, columns per albedo of ``ALBEDO``: the light of the method
#: over Lambert's, semi-infinite medium, IOR 1.45, Roughness 0.35, 128 samples.
#: ``python -m benchmarks.energy --write-table`` rewrites this block from the measurements.
# BEGIN TABLE
SEMI_INFINITE: dict[str, tuple[tuple[float, ...], ...]] = {
    "RANDOM_WALK": (
        (0.781, 0.793, 0.799, 0.806, 0.831, 0.855, 0.876, 0.901, 0.926, 0.948, 0.952, 0.935),  # 0 deg
        (0.791, 0.808, 0.807, 0.824, 0.842, 0.868, 0.880, 0.908, 0.932, 0.952, 0.954, 0.936),  # 20 deg
        (0.831, 0.845, 0.849, 0.862, 0.876, 0.898, 0.909, 0.931, 0.948, 0.964, 0.962, 0.943),  # 40 deg
        (0.875, 0.888, 0.886, 0.896, 0.908, 0.923, 0.935, 0.949, 0.964, 0.975, 0.969, 0.948),  # 55 deg
        (0.913, 0.927, 0.923, 0.926, 0.936, 0.949, 0.957, 0.965, 0.976, 0.983, 0.974, 0.951),  # 65 deg
        (0.957, 0.972, 0.961, 0.969, 0.970, 0.980, 0.978, 0.986, 0.990, 0.994, 0.980, 0.955),  # 75 deg
        (1.055, 1.047, 1.046, 1.036, 1.032, 1.027, 1.024, 1.017, 1.014, 1.008, 0.988, 0.963),  # 85 deg
    ),
    "RANDOM_WALK_SKIN": (
        (0.904, 0.914, 0.912, 0.920, 0.934, 0.947, 0.955, 0.968, 0.978, 0.992, 0.996, 0.961),  # 0 deg
        (0.915, 0.929, 0.924, 0.929, 0.944, 0.959, 0.961, 0.973, 0.983, 0.995, 0.997, 0.960),  # 20 deg
        (0.956, 0.967, 0.964, 0.970, 0.975, 0.987, 0.986, 0.994, 0.998, 1.005, 1.003, 0.966),  # 40 deg
        (1.007, 1.013, 1.011, 1.014, 1.014, 1.015, 1.014, 1.014, 1.014, 1.015, 1.007, 0.970),  # 55 deg
        (1.060, 1.068, 1.060, 1.056, 1.050, 1.047, 1.039, 1.033, 1.028, 1.024, 1.010, 0.973),  # 65 deg
        (1.130, 1.139, 1.117, 1.114, 1.097, 1.089, 1.069, 1.056, 1.045, 1.036, 1.017, 0.975),  # 75 deg
        (1.251, 1.236, 1.219, 1.195, 1.164, 1.139, 1.113, 1.084, 1.064, 1.047, 1.023, 0.982),  # 85 deg
    ),
    "RANDOM_WALK_LEGACY": (
        (0.771, 0.786, 0.796, 0.805, 0.836, 0.861, 0.884, 0.910, 0.936, 0.964, 0.981, 0.946),  # 0 deg
        (0.781, 0.802, 0.804, 0.823, 0.846, 0.874, 0.889, 0.917, 0.942, 0.968, 0.983, 0.947),  # 20 deg
        (0.821, 0.839, 0.846, 0.862, 0.880, 0.905, 0.918, 0.939, 0.959, 0.979, 0.989, 0.953),  # 40 deg
        (0.863, 0.882, 0.883, 0.896, 0.913, 0.930, 0.942, 0.958, 0.974, 0.989, 0.994, 0.958),  # 55 deg
        (0.901, 0.920, 0.920, 0.926, 0.940, 0.956, 0.965, 0.974, 0.986, 0.998, 0.998, 0.961),  # 65 deg
        (0.944, 0.965, 0.959, 0.969, 0.974, 0.988, 0.986, 0.995, 1.000, 1.008, 1.003, 0.963),  # 75 deg
        (1.041, 1.040, 1.043, 1.036, 1.037, 1.034, 1.032, 1.025, 1.023, 1.022, 1.011, 0.971),  # 85 deg
    ),
}
SLAB_ABOVE: dict[str, tuple[tuple[float, ...], ...]] = {
    "RANDOM_WALK": (
        (0.484, 0.666, 0.782, 0.809, 0.812, 0.802, 0.811, 0.810),  # albedo 0.2
        (0.413, 0.613, 0.781, 0.839, 0.840, 0.838, 0.840, 0.845),  # albedo 0.35
        (0.352, 0.547, 0.753, 0.860, 0.873, 0.873, 0.877, 0.877),  # albedo 0.5
        (0.297, 0.480, 0.698, 0.856, 0.903, 0.910, 0.913, 0.916),  # albedo 0.65
        (0.254, 0.414, 0.625, 0.811, 0.915, 0.946, 0.948, 0.948),  # albedo 0.8
        (0.223, 0.369, 0.561, 0.746, 0.875, 0.942, 0.947, 0.948),  # albedo 0.92
    ),
    "RANDOM_WALK_SKIN": (
        (0.607, 0.793, 0.906, 0.920, 0.926, 0.915, 0.930, 0.920),  # albedo 0.2
        (0.520, 0.728, 0.892, 0.939, 0.941, 0.935, 0.943, 0.941),  # albedo 0.35
        (0.440, 0.645, 0.851, 0.941, 0.957, 0.952, 0.960, 0.956),  # albedo 0.5
        (0.374, 0.566, 0.782, 0.924, 0.968, 0.969, 0.974, 0.975),  # albedo 0.65
        (0.309, 0.476, 0.687, 0.855, 0.959, 0.989, 0.993, 0.992),  # albedo 0.8
        (0.263, 0.412, 0.602, 0.774, 0.905, 0.980, 0.988, 0.990),  # albedo 0.92
    ),
    "RANDOM_WALK_LEGACY": (
        (0.484, 0.666, 0.782, 0.809, 0.812, 0.802, 0.811, 0.810),  # albedo 0.2
        (0.414, 0.616, 0.784, 0.844, 0.846, 0.844, 0.844, 0.852),  # albedo 0.35
        (0.354, 0.550, 0.759, 0.867, 0.881, 0.881, 0.886, 0.886),  # albedo 0.5
        (0.298, 0.481, 0.702, 0.863, 0.913, 0.921, 0.921, 0.927),  # albedo 0.65
        (0.255, 0.415, 0.628, 0.817, 0.927, 0.962, 0.964, 0.963),  # albedo 0.8
        (0.224, 0.370, 0.564, 0.753, 0.891, 0.968, 0.977, 0.977),  # albedo 0.92
    ),
    "BURLEY": (
        (1.004, 0.990, 0.990, 0.998, 0.998, 0.999, 0.999, 1.001),  # albedo 0.2
        (1.004, 0.991, 0.991, 0.998, 0.998, 1.000, 1.000, 1.001),  # albedo 0.35
        (1.004, 0.990, 0.990, 0.998, 0.998, 0.999, 0.999, 1.001),  # albedo 0.5
        (1.004, 0.991, 0.991, 0.998, 0.998, 1.000, 1.000, 1.001),  # albedo 0.65
        (1.004, 0.990, 0.990, 0.998, 0.998, 0.999, 0.999, 1.001),  # albedo 0.8
        (1.004, 0.991, 0.991, 0.998, 0.998, 1.000, 1.000, 1.001),  # albedo 0.92
    ),
}
SLAB_BELOW: dict[str, tuple[tuple[float, ...], ...]] = {
    "RANDOM_WALK": (
        (3.463, 2.380, 1.068, 0.202, 0.007, 0.000, 0.000, 0.000),  # albedo 0.2
        (2.106, 1.560, 0.827, 0.222, 0.015, 0.000, 0.000, 0.000),  # albedo 0.35
        (1.530, 1.200, 0.731, 0.278, 0.039, 0.001, 0.000, 0.000),  # albedo 0.5
        (1.204, 0.975, 0.657, 0.327, 0.091, 0.007, 0.000, 0.000),  # albedo 0.65
        (0.988, 0.817, 0.581, 0.346, 0.156, 0.036, 0.005, 0.000),  # albedo 0.8
        (0.863, 0.716, 0.520, 0.329, 0.186, 0.077, 0.006, 0.000),  # albedo 0.92
    ),
    "RANDOM_WALK_SKIN": (
        (3.108, 2.002, 0.818, 0.139, 0.004, 0.000, 0.000, 0.000),  # albedo 0.2
        (1.928, 1.365, 0.680, 0.173, 0.011, 0.000, 0.000, 0.000),  # albedo 0.35
        (1.419, 1.076, 0.627, 0.234, 0.032, 0.001, 0.000, 0.000),  # albedo 0.5
        (1.121, 0.882, 0.574, 0.283, 0.079, 0.007, 0.000, 0.000),  # albedo 0.65
        (0.932, 0.756, 0.525, 0.318, 0.146, 0.040, 0.007, 0.000),  # albedo 0.8
        (0.823, 0.675, 0.485, 0.311, 0.181, 0.091, 0.012, 0.000),  # albedo 0.92
    ),
    "RANDOM_WALK_LEGACY": (
        (3.463, 2.379, 1.068, 0.202, 0.007, 0.000, 0.000, 0.000),  # albedo 0.2
        (2.107, 1.563, 0.830, 0.224, 0.015, 0.000, 0.000, 0.000),  # albedo 0.35
        (1.531, 1.203, 0.734, 0.282, 0.040, 0.001, 0.000, 0.000),  # albedo 0.5
        (1.205, 0.977, 0.660, 0.332, 0.094, 0.008, 0.000, 0.000),  # albedo 0.65
        (0.988, 0.818, 0.583, 0.351, 0.163, 0.042, 0.007, 0.000),  # albedo 0.8
        (0.863, 0.717, 0.523, 0.334, 0.195, 0.092, 0.009, 0.000),  # albedo 0.92
    ),
    "BURLEY": (
        (0.927, 0.836, 0.640, 0.367, 0.118, 0.000, 0.000, 0.000),  # albedo 0.2
        (0.927, 0.836, 0.640, 0.368, 0.118, 0.000, 0.000, 0.000),  # albedo 0.35
        (0.927, 0.836, 0.640, 0.367, 0.118, 0.000, 0.000, 0.000),  # albedo 0.5
        (0.927, 0.836, 0.640, 0.368, 0.118, 0.000, 0.000, 0.000),  # albedo 0.65
        (0.927, 0.836, 0.640, 0.367, 0.118, 0.000, 0.000, 0.000),  # albedo 0.8
        (0.927, 0.836, 0.640, 0.368, 0.118, 0.000, 0.000, 0.000),  # albedo 0.92
    ),
}
CONVEX: dict[str, tuple[tuple[float, ...], ...]] = {
    "RANDOM_WALK": (
        (1.012, 1.030, 1.065, 1.154, 1.366, 2.154),  # albedo 0.05
        (1.013, 1.030, 1.067, 1.161, 1.358, 1.816),  # albedo 0.1
        (1.013, 1.030, 1.067, 1.163, 1.356, 1.684),  # albedo 0.15
        (1.015, 1.033, 1.069, 1.165, 1.359, 1.613),  # albedo 0.2
        (1.014, 1.036, 1.079, 1.174, 1.377, 1.521),  # albedo 0.3
        (1.015, 1.038, 1.083, 1.182, 1.374, 1.420),  # albedo 0.4
        (1.016, 1.037, 1.082, 1.187, 1.339, 1.287),  # albedo 0.5
        (1.017, 1.040, 1.087, 1.186, 1.268, 1.181),  # albedo 0.6
        (1.017, 1.040, 1.089, 1.167, 1.181, 1.094),  # albedo 0.7
        (1.017, 1.039, 1.085, 1.121, 1.079, 1.028),  # albedo 0.8
        (1.018, 1.041, 1.085, 1.050, 1.013, 0.996),  # albedo 0.9
        (1.018, 1.041, 1.082, 1.026, 0.989, 0.978),  # albedo 0.95
    ),
    "RANDOM_WALK_SKIN": (
        (1.016, 1.033, 1.084, 1.260, 1.798, 3.209),  # albedo 0.05
        (1.015, 1.031, 1.072, 1.209, 1.557, 2.307),  # albedo 0.1
        (1.014, 1.029, 1.069, 1.197, 1.476, 2.003),  # albedo 0.15
        (1.015, 1.029, 1.068, 1.190, 1.442, 1.838),  # albedo 0.2
        (1.015, 1.034, 1.076, 1.187, 1.408, 1.626),  # albedo 0.3
        (1.015, 1.035, 1.077, 1.184, 1.374, 1.463),  # albedo 0.4
        (1.015, 1.034, 1.077, 1.180, 1.323, 1.308),  # albedo 0.5
        (1.016, 1.036, 1.081, 1.176, 1.249, 1.187),  # albedo 0.6
        (1.016, 1.036, 1.078, 1.147, 1.159, 1.093),  # albedo 0.7
        (1.017, 1.035, 1.075, 1.100, 1.064, 1.025),  # albedo 0.8
        (1.015, 1.029, 1.061, 1.019, 1.001, 0.994),  # albedo 0.9
        (1.028, 1.059, 1.068, 0.997, 0.985, 0.986),  # albedo 0.95
    ),
    "RANDOM_WALK_LEGACY": (
        (1.013, 1.030, 1.065, 1.155, 1.367, 2.164),  # albedo 0.05
        (1.013, 1.030, 1.068, 1.160, 1.358, 1.819),  # albedo 0.1
        (1.013, 1.030, 1.067, 1.163, 1.356, 1.686),  # albedo 0.15
        (1.014, 1.033, 1.070, 1.166, 1.360, 1.614),  # albedo 0.2
        (1.014, 1.037, 1.081, 1.175, 1.379, 1.522),  # albedo 0.3
        (1.015, 1.039, 1.086, 1.183, 1.375, 1.419),  # albedo 0.4
        (1.016, 1.037, 1.082, 1.189, 1.339, 1.285),  # albedo 0.5
        (1.016, 1.041, 1.089, 1.186, 1.265, 1.178),  # albedo 0.6
        (1.017, 1.041, 1.091, 1.163, 1.175, 1.090),  # albedo 0.7
        (1.017, 1.038, 1.082, 1.110, 1.068, 1.022),  # albedo 0.8
        (1.019, 1.039, 1.080, 1.029, 1.000, 0.990),  # albedo 0.9
        (1.018, 1.038, 1.077, 1.012, 0.988, 0.987),  # albedo 0.95
    ),
    "BURLEY": (
        (1.003, 1.011, 1.030, 1.079, 1.000, 0.750),  # albedo 0.05
        (1.003, 1.011, 1.029, 1.077, 0.996, 0.749),  # albedo 0.1
        (1.003, 1.010, 1.028, 1.076, 0.997, 0.747),  # albedo 0.15
        (1.003, 1.010, 1.030, 1.080, 1.002, 0.752),  # albedo 0.2
        (1.003, 1.010, 1.029, 1.079, 1.002, 0.751),  # albedo 0.3
        (1.003, 1.010, 1.029, 1.078, 0.999, 0.751),  # albedo 0.4
        (1.003, 1.010, 1.029, 1.078, 1.000, 0.750),  # albedo 0.5
        (1.003, 1.010, 1.029, 1.080, 1.003, 0.753),  # albedo 0.6
        (1.003, 1.010, 1.029, 1.080, 1.004, 0.753),  # albedo 0.7
        (1.003, 1.010, 1.030, 1.081, 1.003, 0.754),  # albedo 0.8
        (1.003, 1.010, 1.029, 1.080, 1.003, 0.753),  # albedo 0.9
        (1.003, 1.010, 1.029, 1.080, 1.005, 0.754),  # albedo 0.95
    ),
}
# END TABLE


def _nodes(values) -> np.ndarray:
    return np.asarray(values, dtype=np.float64)


def _entry_table(method: str):
    """``SEMI_INFINITE``'s table of ``method`` as ``entry_gain`` reads it: (table (view cosines,
    albedos), the view cosines ascending, the albedos), or None without one."""
    table = SEMI_INFINITE.get(method)
    if table is None:
        return None
    return np.ascontiguousarray(_nodes(table)[::-1]), np.cos(np.radians(_nodes(VIEW_DEG)))[::-1].copy(), _nodes(ALBEDO)


def _convex_table(method: str):
    """``CONVEX``'s table of ``method`` as ``convex_gain`` reads it: (table (albedos, curvatures),
    the albedos, the curvatures in mean free paths from 0, the flat surface's 1), or None."""
    if method not in CONVEX:
        return None
    table = np.concatenate([np.ones((len(ALBEDO), 1)), _nodes(CONVEX[method])], axis=1)
    return table, _nodes(ALBEDO), np.concatenate([[0.0], 1.0 / _nodes(CONVEX_RADII)])


def _slab_tables(method: str):
    """``SLAB_ABOVE`` and ``SLAB_BELOW`` of ``method`` over the thickest slab's ``SLAB_ABOVE``, as
    ``slab_factors`` reads them: (above, below (albedos, thicknesses), the albedos, log2 of the
    thicknesses)."""
    above, below = _nodes(SLAB_ABOVE[method]), _nodes(SLAB_BELOW[method])
    thick = above[:, -1:]
    return above / thick, below / thick, _nodes(SLAB_ALBEDO), np.log2(_nodes(SLAB_MFPS))


def _log_thickness(t: np.ndarray) -> np.ndarray:
    """``t`` (float64, thicknesses in mean free paths) as ``slab_factors`` reads it, a new array:
    NaN and +inf as the thickest slab, -inf as the thinnest (fmin and fmax take the number over
    NaN, so two passes give what nan_to_num and clip give in six), then log2 (NumPy's)."""
    lt = np.fmin(t, SLAB_MFPS[-1])
    np.fmax(lt, SLAB_MFPS[0], out=lt)
    return np.log2(lt, out=lt)


def entry_gain(method: str, albedo, cos_view) -> np.ndarray:
    """The method's light over Lambert's per channel, float32 (..., 3), for Base Color ``albedo``
    (..., 3) and view cosine ``cos_view`` (...): bilinear in the albedo (clamped to the table's
    0.05..0.95) and in the view cosine (clamped to the table's 0..85 degrees). 1 for a method
    without a table (Christensen-Burley, measured equal to Lambert)."""
    a = np.asarray(albedo, dtype=np.float64)
    mu = np.asarray(cos_view, dtype=np.float64)
    if a.shape[-1:] != (3,) or a.shape[:-1] != mu.shape:
        raise ValueError(f"albedo {a.shape} and cos_view {mu.shape}: expected (..., 3) and (...)")
    tables = _entry_table(method)
    if tables is None:
        return np.ones(a.shape, np.float32)
    t, mus, albedos = tables
    return _lerp2(
        "entry_gain",
        t,
        mus,
        albedos,
        np.broadcast_to(mu[..., None], a.shape),
        a,
        (1.0, albedos[0]),
        lambda: _entry_gain_reference(t, mus, albedos, a, mu),
    )


def _entry_gain_reference(t, mus, albedos, a, mu) -> np.ndarray:
    """``entry_gain``'s table read in NumPy (the reference, ``_lerp2``)."""
    m = np.clip(np.nan_to_num(mu, nan=1.0), mus[0], mus[-1])
    i = np.clip(np.searchsorted(mus, m, side="right") - 1, 0, len(mus) - 2)
    fm = (m - mus[i]) / (mus[i + 1] - mus[i])
    out = np.empty(a.shape, np.float64)
    for c in range(3):
        ac = np.clip(np.nan_to_num(a[..., c], nan=albedos[0]), albedos[0], albedos[-1])
        j = np.clip(np.searchsorted(albedos, ac, side="right") - 1, 0, len(albedos) - 2)
        fa = (ac - albedos[j]) / (albedos[j + 1] - albedos[j])
        lo = t[i, j] * (1 - fa) + t[i, j + 1] * fa
        hi = t[i + 1, j] * (1 - fa) + t[i + 1, j + 1] * fa
        out[..., c] = lo * (1 - fm) + hi * fm
    return out.astype(np.float32)


def slab_factors(method: str, albedo, thickness_mfp) -> tuple[np.ndarray, np.ndarray]:
    """(f_above, f_below), float32 (..., 3): ``SLAB_ABOVE`` and ``SLAB_BELOW`` for ``method`` at
    Base Color ``albedo`` (..., 3) and thickness ``thickness_mfp`` (..., 3, mean free paths), both
    over the thickest slab's ``SLAB_ABOVE`` (the semi-infinite medium, whose entry ``entry_gain``
    gives). Linear in the albedo, linear in log2 of the thickness; clamped to the tables (a
    thickness above 128 mean free paths reads as 128: 1 and 0). A method without tables: (1, 0)."""
    a = np.asarray(albedo, dtype=np.float64)
    t = np.asarray(thickness_mfp, dtype=np.float64)
    if a.shape != t.shape or a.shape[-1:] != (3,):
        raise ValueError(f"albedo {a.shape} and thickness_mfp {t.shape}: expected the same (..., 3)")
    if method not in SLAB_ABOVE:
        return np.ones(a.shape, np.float32), np.zeros(a.shape, np.float32)
    above, below, albedos, logs = _slab_tables(method)
    lt = _log_thickness(t)  # (0.03 s against 0.07 s with nan_to_num and clip, 1080p x 3)
    f_above, f_below = (
        _lerp2(
            "slab_factors",
            table,
            albedos,
            logs,
            a,
            lt,
            (albedos[0], logs[-1]),
            lambda table=table: _slab_reference(table, albedos, logs, a, lt),
        )
        for table in (above, below)
    )
    return f_above, f_below


def _slab_reference(table, albedos, logs, a, lt) -> np.ndarray:
    """``slab_factors``' read of one of its tables in NumPy (the reference, ``_lerp2``)."""
    i = np.clip(np.searchsorted(logs, lt, side="right") - 1, 0, len(logs) - 2)
    ft = (lt - logs[i]) / (logs[i + 1] - logs[i])
    ac = np.clip(np.nan_to_num(a, nan=albedos[0]), albedos[0], albedos[-1])
    j = np.clip(np.searchsorted(albedos, ac, side="right") - 1, 0, len(albedos) - 2)
    fa = (ac - albedos[j]) / (albedos[j + 1] - albedos[j])
    lo = table[j, i] * (1 - ft) + table[j, i + 1] * ft
    hi = table[j + 1, i] * (1 - ft) + table[j + 1, i + 1] * ft
    return (lo * (1 - fa) + hi * fa).astype(np.float32)


def convex_gain(method: str, albedo, curvature_mfp) -> np.ndarray:
    """``CONVEX`` for ``method`` at Base Color ``albedo`` (..., 3) and mean curvature times the
    method's mean free path ``curvature_mfp`` (..., 3; l / R on a sphere of radius R), float32
    (..., 3): linear in the albedo and in the curvature, 1 at a flat surface, clamped to the
    table's largest curvature; 1 where the surface is flat or concave (not measured) and for a
    method without a table."""
    a = np.asarray(albedo, dtype=np.float64)
    k = np.asarray(curvature_mfp, dtype=np.float64)
    if a.shape != k.shape or a.shape[-1:] != (3,):
        raise ValueError(f"albedo {a.shape} and curvature_mfp {k.shape}: expected the same (..., 3)")
    if method not in CONVEX:
        return np.ones(a.shape, np.float32)
    table, albedos, nodes = _convex_table(method)
    return _lerp2(
        "convex_gain", table, albedos, nodes, a, k, (albedos[0], 0.0), lambda: _convex_reference(table, nodes, a, k)
    )


def _lerp2(name, table, rows, cols, rv, cv, nan_values, reference) -> np.ndarray:
    """A bilinear read of ``table`` (float64, rows x columns at the ascending ``rows`` and
    ``cols`` nodes) at ``rv`` and ``cv`` (float64, one shape; NaN read as ``nan_values``, both
    clipped to the nodes), float32: ``reference()``, the NumPy code, or on the compiled backend
    ``core.optics._kernels.table_lerp``, the same float64 operations in the same order (equal to the
    bit: check mode compares with bound 0). The NumPy code makes some twenty passes over
    float64 arrays of every pixel and channel, with gathers by index arrays (about 1.7 s for
    ``convex_gain`` over a 1080p frame, loaded machine); the kernel one."""
    mode = backend.active()
    if mode == "numpy":
        return reference()
    c = np.ascontiguousarray
    out = np.empty(rv.shape, np.float32)
    rv, cv = c(rv, np.float64).reshape(-1), c(cv, np.float64).reshape(-1)
    backend.run_kernel(
        _kernels().table_lerp,
        c(table, np.float64),
        c(rows),
        c(cols),
        rv,
        cv,
        *nan_values,
        out.reshape(-1),
    )
    if mode == "check":
        backend.compare(name, reference(), out, np.zeros(out.shape))
    return out


def _convex_reference(table, nodes, a, k) -> np.ndarray:
    """``convex_gain``'s table read in NumPy (the reference, ``_lerp2``)."""
    kc = np.clip(np.nan_to_num(k, nan=0.0), 0.0, nodes[-1])
    i = np.clip(np.searchsorted(nodes, kc, side="right") - 1, 0, len(nodes) - 2)
    fk = (kc - nodes[i]) / (nodes[i + 1] - nodes[i])
    albedos = _nodes(ALBEDO)
    ac = np.clip(np.nan_to_num(a, nan=albedos[0]), albedos[0], albedos[-1])
    j = np.clip(np.searchsorted(albedos, ac, side="right") - 1, 0, len(albedos) - 2)
    fa = (ac - albedos[j]) / (albedos[j + 1] - albedos[j])
    lo = table[j, i] * (1 - fk) + table[j, i + 1] * fk
    hi = table[j + 1, i] * (1 - fk) + table[j + 1, i + 1] * fk
    return (lo * (1 - fa) + hi * fa).astype(np.float32)


def _box_sum(a: np.ndarray, radius: int) -> np.ndarray:
    """The sum of each pixel's (2 radius + 1)^2 neighbourhood (zero outside the image), by
    cumulative sums."""
    out = np.asarray(a, np.float64)
    for axis in (0, 1):
        pad = [(0, 0), (0, 0)]
        pad[axis] = (radius + 1, radius)
        c = np.cumsum(np.pad(out, pad), axis=axis)
        n = out.shape[axis]
        out = np.take(c, np.arange(2 * radius + 1, 2 * radius + 1 + n), axis=axis) - np.take(c, np.arange(n), axis=axis)
    return out


def surface_curvature(normal, position, mask, radius_px: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(mean, largest) curvature of the surface seen at each pixel (1 / scene units; > 0 convex,
    < 0 concave), float32 (H, W) each, from world-space ``normal`` and ``position`` (H, W, 3):
    along each image axis the normal curvature (n_b - n_a) . (p_b - p_a) / |p_b - p_a|^2 between
    the pixel's two neighbours on ``mask`` (1 / R on a sphere of radius R in every direction), or
    between the pixel and its one neighbour on the mask; "mean" is the mean of both axes (a
    cylinder of radius R reads 1 / (2 R)), "largest" the larger (1 / R on the cylinder where an
    image axis crosses it). Each is then averaged over the pixels on the mask within
    ``radius_px`` (a square of 2 radius_px + 1; a flat-shaded mesh's edges spread over the faces
    beside them, as far as a walk reaches); 0 where no neighbour is on the mask."""
    r = max(1, int(radius_px))
    mean, largest = _smoothed_curvatures(_curvature_per_pixel(normal, position, mask), [r])[r]
    assert largest is not None
    return mean, largest


def _curvature_per_pixel(normal, position, mask):
    """``surface_curvature`` before its average: (mean, largest, valid, on) per pixel. On the
    compiled backend ``core.optics._kernels.curvature_pixels``, the same float32 and float64 operations
    in the same order (equal to the bit: check mode compares with bound 0); the NumPy code is the
    reference."""
    mode = backend.active()
    if mode == "numpy":
        return _curvature_reference(normal, position, mask)
    c = np.ascontiguousarray
    n = c(np.asarray(normal, np.float32)[..., :3])
    p = c(np.asarray(position, np.float32)[..., :3])
    m = c(np.asarray(mask, dtype=bool))
    shape = m.shape
    parts = (np.empty(shape), np.empty(shape), np.empty(shape, bool), np.empty(shape, bool))
    backend.run_kernel(_kernels().curvature_pixels, n, p, m, np.empty(n.shape, np.float32), *parts)
    if mode == "check":
        for name, ref, got in zip(
            ("mean", "largest", "valid", "on"), _curvature_reference(n, p, m), parts, strict=True
        ):
            backend.compare(
                f"surface_curvature ({name})", np.asarray(ref, np.float64), got.astype(np.float64), np.zeros(shape)
            )
    return parts


def _curvature_reference(normal, position, mask):
    """``_curvature_per_pixel`` in NumPy: the reference."""
    n = np.asarray(normal, np.float32)[..., :3]
    p = np.asarray(position, np.float32)[..., :3]
    m = np.asarray(mask, dtype=bool) & np.isfinite(n).all(-1) & np.isfinite(p).all(-1)
    length = np.sqrt(np.einsum("...i,...i->...", n, n))[..., None]
    m &= length[..., 0] > 0.5
    n = np.where(m[..., None], n / np.where(length > 0, length, np.float32(1.0)), np.float32(0.0))
    total = np.zeros(m.shape)
    count = np.zeros(m.shape)
    most = np.full(m.shape, -np.inf)
    for axis in (0, 1):
        ok_n = np.roll(m, -1, axis=axis)
        ok_p = np.roll(m, 1, axis=axis)
        if axis == 0:
            ok_n[-1, :] = False
            ok_p[0, :] = False
        else:
            ok_n[:, -1] = False
            ok_p[:, 0] = False
        n_b = np.where(ok_n[..., None], np.roll(n, -1, axis=axis), n)
        p_b = np.where(ok_n[..., None], np.roll(p, -1, axis=axis), p)
        n_a = np.where(ok_p[..., None], np.roll(n, 1, axis=axis), n)
        p_a = np.where(ok_p[..., None], np.roll(p, 1, axis=axis), p)
        dp = p_b - p_a
        dd = np.einsum("...i,...i->...", dp, dp)
        ok = m & (ok_n | ok_p) & (dd > 0)
        k = np.where(ok, np.einsum("...i,...i->...", n_b - n_a, dp) / np.where(ok, dd, np.float32(1.0)), 0.0)
        total += k
        count += ok
        most = np.where(ok, np.maximum(most, k), most)
    valid = count > 0
    return np.where(valid, total / np.maximum(count, 1), 0.0), np.where(valid, most, 0.0), valid, m


def _smoothed_curvatures(parts, radii) -> dict[int, tuple[np.ndarray, np.ndarray | None]]:
    """``surface_curvature``'s average of ``_curvature_per_pixel``'s ``parts`` over each radius of
    ``radii`` (pixels, each at least 1): {radius: (mean, largest)}, the largest curvature's only
    at the widest radius (None at the others). On the compiled backend one call of
    ``core.optics._kernels.smooth_curvature`` for all radii (equal to the bit, as above)."""
    rs = sorted({max(1, int(r)) for r in radii})
    mode = backend.active()
    if mode == "numpy":
        return {r: _smoothed_reference(parts, r, largest=r == rs[-1]) for r in rs}
    c = np.ascontiguousarray
    mean, most, valid, m = (c(v) for v in parts)
    means = np.empty((len(rs), *m.shape), np.float32)
    widest = np.empty(m.shape, np.float32)
    backend.run_kernel(_kernels().smooth_curvature, mean, most, valid, m, np.array(rs, np.int64), True, means, widest)
    result = {r: (means[k], widest if r == rs[-1] else None) for k, r in enumerate(rs)}
    if mode == "check":
        for r in rs:
            for ref, got in zip(_smoothed_reference(parts, r, r == rs[-1]), result[r], strict=True):
                if ref is not None and got is not None:
                    backend.compare("surface_curvature (average)", ref, got, np.zeros(m.shape))
    return result


def _smoothed_reference(parts, radius_px: int, largest: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """``_smoothed_curvatures`` at one radius in NumPy: the reference."""
    mean, most, valid, m = parts
    weight = valid.astype(np.float64)
    r = max(1, int(radius_px))
    near = _box_sum(weight, r)
    out: list = []
    for h in (mean, most) if largest else (mean,):
        out.append(np.where(m & (near > 0), _box_sum(h * weight, r) / np.maximum(near, 1.0), 0.0).astype(np.float32))
    return out[0], out[1] if largest else None


def mean_lamp_irradiance(lights, normal, position) -> np.ndarray:
    """The mean over the rows of the sum over ``lights`` of colour x E_L max(0, N . L) / pi (the
    Diffuse Direct pass's units), unshadowed, float64 (3,), for unit normals and positions (N,
    3): per light the mean of E_L max(0, N . L) / pi times its colour (one value per pixel, not
    three: a frame of colours per light cost a sixth of the energy stage at 1080p)."""
    from .lights import light_at

    n = np.asarray(normal, np.float64)
    p = np.asarray(position, np.float32)
    out = np.zeros(3, np.float64)
    if not n.shape[0]:
        return np.full(3, np.nan)  # the mean of no rows, as NumPy's
    for light in lights:
        if light.energy <= 0:
            continue
        lx, ly, lz, e = light_at(light, p[:, 0], p[:, 1], p[:, 2])
        c = np.maximum(n[:, 0] * lx + n[:, 1] * ly + n[:, 2] * lz, 0.0) * np.asarray(e, np.float64) / np.pi
        out += c.mean() * np.asarray(light.color, np.float64)
    return out


def unseen_irradiance(*, irradiance, normal, position, lights, lamps: bool = True) -> np.ndarray:
    """The mean irradiance (3,) of the surfaces of an object the camera does not see, from its
    visible pixels' measured ``irradiance`` (N, 3, Diffuse Direct + Indirect), world-space
    ``normal`` and ``position`` (N, 3): each lamp's unshadowed irradiance on the visible normals
    reversed (-n: the opposite surface, docs/references.md §15), averaged, plus the visible light
    the lamps do not explain (the mean measured irradiance less the mean unshadowed lamp
    irradiance, at least 0: a world or bounce light, taken to reach the unseen side as much).
    ``lamps`` False leaves the lamps out (the combined technique adds their light from behind
    itself).

    Why reversed: a convex object symmetric about its centre (a sphere, a box, a slab, a cylinder,
    an ellipsoid) has opposite every visible surface element one the camera does not see, of the
    same area, normal -n and the same |n . v|, so the visible pixels, reversed, sample its unseen
    surface as they sample the seen one. (Mirroring them across the view direction instead, n -
    2 (n . v) v, gives the same mean on a sphere but invents faces on a box: the top face seen
    from above-front becomes a back face tilted up, lit by a lamp above.)"""
    n = np.asarray(normal, np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    pos = np.asarray(position, np.float64)
    visible = mean_lamp_irradiance(lights, n, pos)
    other = np.maximum(np.asarray(irradiance, np.float64).mean(axis=0) - visible, 0.0)
    if not lamps:
        return other
    return mean_lamp_irradiance(lights, -n, pos) + other


def _float_frame(a) -> np.ndarray:
    """``a`` contiguous for a kernel, float32 or float64 as it is (other types as float64)."""
    a = np.asarray(a)
    return np.ascontiguousarray(a if a.dtype in (np.float32, np.float64) else a.astype(np.float64))


def unseen_light(mask, *, diffuse, albedo, pre_post, normal, position, lights, lamps):
    """``apply_energy``'s light of the surfaces the camera does not see: ``unseen_irradiance`` of
    the pixels of ``mask`` whose normal and position are finite and whose normal is longer than 0
    (their light ``diffuse``, over the albedo with ``pre_post``), float64 (3,), or None without
    such pixels.

    On the compiled backend ``core.optics._kernels.unseen_sums`` sums each row's terms (every pixel's
    terms the reference's operations in its order) without gathering the pixels into float64
    arrays (0.8 s of the energy stage's 1.4 s at 1080p, loaded machine); the means differ from
    the reference's only in the order of their float64 sums (the bound: ``_U64``'s comment)."""
    mode = backend.active()

    def reference():
        e = np.asarray(diffuse, dtype=np.float32)[mask]
        if pre_post:
            e = e / np.maximum(np.asarray(albedo, dtype=np.float32)[mask], np.float32(1e-6))
        nrm = np.asarray(normal, np.float64)[mask]
        pos = np.asarray(position, np.float64)[mask]
        ok = np.isfinite(nrm).all(axis=1) & np.isfinite(pos).all(axis=1) & (np.linalg.norm(nrm, axis=1) > 0)
        if not ok.any():
            return None, 0.0
        got = unseen_irradiance(irradiance=e[ok], normal=nrm[ok], position=pos[ok], lights=lights, lamps=lamps)
        return got, np.abs(e[ok].astype(np.float64)).mean(axis=0)

    if mode == "numpy":
        return reference()[0]
    active = [light for light in lights if light.energy > 0]
    table = _kernels().light_table(active)
    m = np.ascontiguousarray(mask, dtype=bool)
    h = m.shape[0]
    count, light = np.zeros(h, np.int64), np.zeros((h, 3), np.float64)
    seen, behind = np.zeros((h, len(active)), np.float64), np.zeros((h, len(active)), np.float64)
    diffuse32 = np.ascontiguousarray(diffuse, np.float32)
    albedo32 = np.ascontiguousarray(albedo, np.float32) if pre_post else diffuse32
    args = (
        _float_frame(normal),
        _float_frame(position),
        diffuse32,
        albedo32,
        bool(pre_post),
        m,
        table,
        bool(lamps),
    )
    backend.run_kernel(_kernels().unseen_sums, *args, count, light, seen, behind)
    n = int(count.sum())
    if n == 0:
        result = None
    else:
        colors = [np.asarray(lt.color, np.float64) for lt in active]

        def mean_lamps(sums):
            out = np.zeros(3, np.float64)
            for k, color in enumerate(colors):
                out += sums[k] / n * color
            return out

        other = np.maximum(light.sum(axis=0) / n - mean_lamps(seen.sum(axis=0)), 0.0)
        result = mean_lamps(behind.sum(axis=0)) + other if lamps else other
    if mode == "check":
        expected, magnitude = reference()
        if (expected is None) != (result is None):
            raise backend.BackendMismatch("unseen_light: the compiled and NumPy backends disagree on its pixels")
        if result is not None:
            lamp = np.zeros(3)
            if colors:  # the lamps' terms are >= 0: the magnitude of their sums is their sums'
                lamp = (np.abs(seen.sum(axis=0)) + np.abs(behind.sum(axis=0))) @ np.abs(np.stack(colors)) / n
            backend.compare("unseen_light", expected, result, (2.0 * n + 8.0) * _U64 * (magnitude + lamp))
    return result


#: The unit roundoff of float64. ``unseen_light``'s check bounds |compiled - reference| of its
#: means of n pixels by (2 n + 8) u times the mean magnitude of the terms: each of the two float64
#: sums (recursive along rows, or NumPy's pairwise) is within (n - 1) u of the exact sum relative to
#: the sum of the terms' magnitudes (Higham, "Accuracy and Stability of Numerical Algorithms", 2nd
#: ed., §4.2), plus the means' few roundings after the sums (a division, a product by the colour
#: and the sums over lights and terms: within 8 u).
_U64 = 2.0**-53


def view_cosine(depth, mask, camera: Camera, *, origin=(0, 0), frame=None) -> np.ndarray:
    """|cos| of the angle between the surface normal and the direction to the camera, float32
    (H, W), from the planar Depth pass: each pixel is unprojected to camera space, the normal is
    the cross product of its horizontal and vertical differences (on each axis the smaller of the
    two one-sided differences to a neighbour of ``mask``, so that a silhouette does not bend it).
    1 (facing the camera) where no neighbour is on the mask. ``depth`` and ``mask`` may be a
    window of the frame: ``origin`` (row, column) its first pixel, ``frame`` (H, W) the frame's
    size (default: the window's).

    On the compiled backend ``core.optics._kernels.view_cosine``, the same float64 operations in the same
    order per pixel (equal to the bit: check mode compares with bound 0); the NumPy code makes some
    forty passes over float64 frames of three components (0.5 s at 1080p, loaded machine)."""
    mode = backend.active()
    if mode != "numpy":
        h, w = np.shape(mask) if frame is None else frame
        ortho = camera.type == "ORTHO"
        cx, cy = camera.principal_point(w, h)
        z = _float_frame(depth)
        out = np.empty(z.shape, np.float32)
        f = float(camera.ortho_px_per_unit if ortho else camera.focal_px)
        far = float(arrays.BACKGROUND_DEPTH)  # compared in float64, as the reference's
        ok = np.ascontiguousarray(mask, dtype=bool)
        if ok.shape != z.shape or z.ndim != 2:
            raise ValueError(f"depth {z.shape} and mask {ok.shape}: expected two images of the same size")
        backend.run_kernel(
            _kernels().view_cosine,
            z,
            ok,
            far,
            ortho,
            f,
            float(cx),
            float(cy),
            int(origin[0]),
            int(origin[1]),
            out,
        )
        if mode == "check":
            with backend.use("numpy"):
                reference = view_cosine(depth, mask, camera, origin=origin, frame=frame)
            backend.compare("view_cosine", reference, out, np.zeros(out.shape))
        return out
    z = np.asarray(depth, dtype=np.float64)
    m = np.asarray(mask, dtype=bool) & np.isfinite(z) & (z > 0) & (z < arrays.BACKGROUND_DEPTH)
    h, w = z.shape if frame is None else frame
    ys, xs = np.mgrid[origin[0] : origin[0] + z.shape[0], origin[1] : origin[1] + z.shape[1]].astype(np.float64)
    if camera.type == "ORTHO":
        s = 1.0 / camera.ortho_px_per_unit
        p = np.stack([(xs + 0.5 - w / 2) * s, (h / 2 - ys - 0.5) * s, -z], axis=-1)
    else:
        f = camera.focal_px
        cx, cy = camera.principal_point(w, h)
        p = np.stack([(xs + 0.5 - cx) / f * z, (cy - ys - 0.5) / f * z, -z], axis=-1)

    def diff(axis):
        nxt = np.roll(p, -1, axis=axis) - p
        prv = p - np.roll(p, 1, axis=axis)
        ok_n = np.roll(m, -1, axis=axis)
        ok_p = np.roll(m, 1, axis=axis)
        if axis == 0:
            ok_n[-1, :] = False
            ok_p[0, :] = False
        else:
            ok_n[:, -1] = False
            ok_p[:, 0] = False
        ln = np.where(ok_n, np.abs(nxt[..., 2]), np.inf)
        lp = np.where(ok_p, np.abs(prv[..., 2]), np.inf)
        return np.where((ln <= lp)[..., None], nxt, prv), ok_n | ok_p

    dx, okx = diff(1)
    dy, oky = diff(0)
    v = -p if camera.type != "ORTHO" else np.broadcast_to(np.array([0.0, 0.0, 1.0]), p.shape)
    # Pixels without a finite depth or neighbour give inf and NaN here; ``ok`` leaves them out.
    with np.errstate(invalid="ignore", divide="ignore"):
        n = np.cross(dx, dy)
        cos = np.abs((n * v).sum(-1)) / (np.linalg.norm(n, axis=-1) * np.linalg.norm(v, axis=-1))
    ok = m & okx & oky & np.isfinite(cos)
    return np.where(ok, np.clip(cos, 0.0, 1.0), 1.0).astype(np.float32)


def normal_view_cosine(normal, mask, camera: Camera, *, origin=(0, 0), frame=None) -> tuple[np.ndarray, np.ndarray]:
    """(|cos| of the angle between the Normal pass's normal and the pixel's ray to the camera,
    float32 (H, W); where it is known, bool (H, W)) on a window of the frame (``origin`` and
    ``frame`` as ``view_cosine``'s). Known: on ``mask``, with a finite normal longer than 1e-6
    (a pixel that a silhouette shares with the background holds the object's normal, shortened by
    the pixel filter, which the length divides away). The ray is the camera model's through the
    pixel's centre, not the Position pass's direction to the camera, which the pixel filter mixes
    with the background's at a silhouette. Elsewhere 1."""
    raw = np.asarray(normal)[..., :3]
    m = np.asarray(mask, dtype=bool)
    h, w = m.shape if frame is None else frame
    rot = np.asarray(camera.matrix_world, np.float64).reshape(4, 4)[:3, :3]
    rot = rot / np.maximum(np.linalg.norm(rot, axis=0, keepdims=True), 1e-30)  # unit camera axes
    mode = backend.active()
    if mode != "numpy":
        if raw.shape[:2] != m.shape:
            raise ValueError(f"normal {raw.shape} and mask {m.shape}: expected images of the same size")
        ortho = camera.type == "ORTHO"
        f = float(camera.ortho_px_per_unit if ortho else camera.focal_px)
        cx, cy = camera.principal_point(w, h)
        out, known = np.empty(m.shape, np.float32), np.empty(m.shape, np.bool_)
        c = np.ascontiguousarray
        backend.run_kernel(
            _kernels().normal_cosine, c(raw, np.float32), c(m), c(rot, np.float32), ortho, f, float(cx), float(cy),
            int(origin[0]), int(origin[1]), out, known,
        )  # fmt: skip
        if mode == "check":
            with backend.use("numpy"):
                ref, ref_known = normal_view_cosine(normal, mask, camera, origin=origin, frame=frame)
            backend.compare("normal_view_cosine", ref, out, np.zeros(out.shape))
            if not np.array_equal(ref_known, known):
                raise backend.BackendMismatch(
                    "normal_view_cosine: the compiled and NumPy backends disagree on its pixels"
                )
        return out, known
    n = raw.astype(np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        # Divided by its largest component first: a normal of any finite length keeps its squares finite.
        u = n / np.abs(n).max(axis=-1, keepdims=True)
    # The normal in camera space (x right, y up, z towards the viewer): the axes' dot products.
    if camera.type != "ORTHO":
        f = camera.focal_px
        cx, cy = camera.principal_point(w, h)
        ys, xs = np.ogrid[origin[0] : origin[0] + m.shape[0], origin[1] : origin[1] + m.shape[1]]
        rx = ((cx - xs - 0.5) / f).astype(np.float32)  # the ray towards the camera, z = 1
        ry = ((ys + 0.5 - cy) / f).astype(np.float32)
    # A NaN or infinite normal gives NaN here; ``known`` leaves it out.
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        r = rot.astype(np.float32)
        nc = [u[..., 0] * r[0, j] + u[..., 1] * r[1, j] + u[..., 2] * r[2, j] for j in range(3)]
        length = np.sqrt(nc[0] * nc[0] + nc[1] * nc[1] + nc[2] * nc[2])
        if camera.type == "ORTHO":
            dot = nc[2]
        else:
            dot = (nc[0] * rx + nc[1] * ry + nc[2]) / np.sqrt(rx * rx + ry * ry + np.float32(1.0))
        cos = np.abs(dot) / length
    known = m & np.isfinite(cos) & (length > np.float32(1e-6))
    return np.where(known, np.minimum(cos, np.float32(1.0)), np.float32(1.0)).astype(np.float32), known


def entry_view_cosine(depth, normal, mask, camera: Camera, box) -> np.ndarray:
    """The entry gain's view cosine on ``box`` (a window of the frame) of the pixels of ``mask``
    (H, W): from
    the Normal pass where ``normal`` is given and known there (``normal_view_cosine``: the shading
    normal, smooth across a mesh's faces), else from the Depth pass (``view_cosine``: the cross
    product of neighbouring depths, which a faceted mesh or an object a few pixels across makes
    coarse: 0.09 from the Normal pass's cosine on spheres 10 px across, docs/references.md §15).
    float32 (box's shape)."""
    mb = np.asarray(mask, dtype=bool)[box]
    origin = (box[0].start, box[1].start)
    shape = np.shape(mask)
    if normal is not None:
        cos, known = normal_view_cosine(np.asarray(normal)[box], mb, camera, origin=origin, frame=shape)
        missing = mb & ~known
        if not missing.any():
            return cos
        fallback = view_cosine(np.asarray(depth)[box], mb, camera, origin=origin, frame=shape)
        return np.where(missing, fallback, cos).astype(np.float32)
    return view_cosine(np.asarray(depth)[box], mb, camera, origin=origin, frame=shape)


#: The keywords of ``apply_energy`` besides ``out``: a diffusion passes its own arguments of these
#: names (``energy_inputs``).
ENERGY_INPUTS = (
    "diffuse",
    "albedo",
    "depth",
    "mask",
    "camera",
    "subsurface_method",
    "energy",
    "albedo_mode",
    "normal",
    "position",
    "thickness",
    "lights",
    "mfp_su",
    "thickness_distance_su",
    "thickness_convention",
    "lamps_behind",
)


def energy_inputs(arguments: dict) -> dict:
    """The entries of ``arguments`` (a diffusion's keyword arguments) that ``apply_energy`` takes."""
    return {k: arguments[k] for k in ENERGY_INPUTS if k in arguments}


def apply_energy(
    out,
    *,
    diffuse,
    albedo,
    depth,
    mask,
    camera: Camera,
    subsurface_method: str | None,
    energy: str,
    albedo_mode: str,
    normal=None,
    position=None,
    thickness=None,
    lights=(),
    mfp_su=None,
    thickness_distance_su: float = 0.0,
    thickness_convention: str = "translucency",
    lamps_behind: bool = True,
):
    """``out`` (H, W, 3, a diffusion's result: albedo x its light) with its pixels on ``mask``
    given the light of Cycles' ``subsurface_method`` (module docstring). "view" multiplies them by
    the entry's gain g, scaled per channel so that the mask's total is what it was (the view
    dependence, the passes' energy). "object" with ``normal`` and ``position`` (H, W, 3) and
    ``mfp_su`` (the method's length per channel) multiplies them by g as measured and by the
    convex surface's gain c (``convex_gain`` at the mean curvature, ``surface_curvature``), and
    with ``thickness`` (H, W, the baked map) and ``thickness_distance_su`` D > 0 as well returns
    g c' (out x f_above + albedo x f_below x E_unseen), the finite object's light, where c' fades
    c towards 1 on an object thinner than the curvature's sphere (x < 2 / largest curvature: a
    curved shell is a slab) and a pixel whose map reads "no far side within D" is given the
    sphere's chord 2 / (largest curvature), at least D and at most ``CHORD_CAP`` D (the object's
    size). Without ``normal`` or ``position`` "object" is "view". g reads the view cosine from
    ``normal`` where it is given (``entry_view_cosine``), else from ``depth``. ``diffuse`` and ``albedo`` are
    the diffusion's inputs (in the "pre-post" mode sqrt(A) x E and sqrt(A)).
    ``subsurface_method`` None (unknown) or "lambert": ``out`` unchanged."""
    if energy not in ENERGY_MODES:
        raise ValueError(f"energy: {energy!r} is not one of {', '.join(ENERGY_MODES)}")
    method = subsurface_method
    if energy == "lambert" or method is None:
        return out
    m = np.asarray(mask, dtype=bool)
    box = arrays.bounding_box(m)
    if box is None:
        return out
    # The view cosine and the curvature on the mask's bounding box only (they read nothing else).
    mb = m[box]
    mu = entry_view_cosine(depth, normal, m, camera, box)
    shaped = energy == "object" and normal is not None and position is not None and mfp_su is not None
    if not shaped:
        a = np.asarray(albedo, dtype=np.float32)[m]
        if albedo_mode == "pre-post":
            a = a * a
        light = out[m]
        gain = entry_gain(method, a.astype(np.float64), mu[mb])
        # The entry's dependence on the view angle, each channel's total over the mask kept.
        before = light.astype(np.float64).sum(axis=0)
        after = (light * gain).astype(np.float64).sum(axis=0)
        gain = gain * np.where(after > 0, before / np.where(after > 0, after, 1.0), 1.0).astype(np.float32)[None, :]
        out[m] = light * gain
        return out
    ell = np.maximum(arrays.rgb_lengths(mfp_su, "mfp_su").astype(np.float64), 1e-30)
    # The curvature over the reach of a walk, a mean free path, per channel (its pixels at the
    # material's median depth, at least 1 and at most CURVATURE_REACH_PX).
    scales = camera.pixels_per_unit(np.asarray(depth, np.float32)[box][mb])  # per pixel: on the mask only
    scales = scales[scales > 0]
    ppu = arrays.median(scales) if scales.size else 0.0  # ``scales`` is a copy, without NaN
    reach = [int(np.clip(round(v * ppu), 1, CURVATURE_REACH_PX)) for v in ell]
    nb, pb = np.asarray(normal)[box], np.asarray(position)[box]
    parts = _curvature_per_pixel(nb, pb, mb)
    # The largest curvature is read at the widest reach only.
    maps = _smoothed_curvatures(parts, reach)
    finite = thickness is not None and thickness_distance_su > 0 and method in SLAB_ABOVE
    unseen = None
    if finite:
        unseen = unseen_light(
            m,
            diffuse=diffuse,
            albedo=albedo,
            pre_post=albedo_mode == "pre-post",
            normal=normal,
            position=position,
            lights=lights,
            lamps=lamps_behind,
        )
    widest = maps[max(reach)][1]
    assert widest is not None
    shape = _ObjectShape(m, box, mu, [maps[r][0] for r in reach], widest, ell, finite, unseen)
    kw = dict(
        method=method,
        albedo=albedo,
        pre_post=albedo_mode == "pre-post",
        thickness=thickness,
        distance=float(thickness_distance_su),
        as_thickness=thickness_convention == "thickness",
    )
    mode = backend.active()
    frame = isinstance(out, np.ndarray) and out.dtype == np.float32 and out.ndim == 3 and out.flags.c_contiguous
    if mode == "numpy" or not frame:  # the kernel writes into a float32 frame
        _object_reference(out, shape, **kw)
        return out
    expected = None
    if mode == "check":
        expected = out.copy()
        _object_reference(expected, shape, **kw)
    _object_compiled(out, shape, **kw)
    if expected is not None:
        backend.compare("energy (object)", expected, out, np.zeros(out.shape))
    return out


@dataclass
class _ObjectShape:
    """What ``apply_energy``'s "object" light reads besides the passes: the mask ``m``, its
    bounding box ``box``, on the box the view cosine ``mu``, the mean curvature per channel
    (``mean``, at each channel's reach) and the largest (``largest``), float32; the mean free
    paths ``ell`` (3,); whether the slab is modelled (``finite``) and the unseen side's light
    (``unseen``, float64 (3,), or None)."""

    m: np.ndarray
    box: tuple[slice, slice]
    mu: np.ndarray
    mean: list
    largest: np.ndarray
    ell: np.ndarray
    finite: bool
    unseen: np.ndarray | None


def _object_reference(out, s: _ObjectShape, *, method, albedo, pre_post, thickness, distance, as_thickness) -> None:
    """``apply_energy``'s "object" light in NumPy (the reference): ``out`` on the mask, in place."""
    m, mb = s.m, s.m[s.box]
    a = np.asarray(albedo, dtype=np.float32)[m]
    if pre_post:
        a = a * a
    light = out[m]
    a64 = a.astype(np.float64)  # what the three table reads below take: converted once
    gain = entry_gain(method, a64, s.mu[mb])
    mean = np.stack([v[mb] for v in s.mean], axis=1).astype(np.float64)
    largest = s.largest[mb].astype(np.float64)
    convex = convex_gain(method, a64, mean * s.ell[None, :])
    if s.finite:
        tau = np.clip(np.nan_to_num(np.asarray(thickness, np.float64)[m]), 0.0, 1.0)
        if as_thickness:
            tau = 1.0 - tau
        x = distance * np.sqrt(1.0 - tau)  # the slab law of core/scene/thickness.py
        # No far side within D: the sphere's chord along the normal, within the object's size.
        chord = 2.0 / np.maximum(largest, 2.0 / (CHORD_CAP * distance))
        x = np.where(tau <= 1e-6, np.maximum(x, chord), x)
        f_above, f_below = slab_factors(method, a64, x[:, None] / s.ell[None, :])
        if s.unseen is not None:
            light = light * f_above + a * f_below * s.unseen.astype(np.float32)[None, :]
        # A shell thinner than its curvature's sphere is a slab: the slab tables hold its light.
        shell = np.clip(x * np.maximum(largest, 0.0) / 2.0, 0.0, 1.0).astype(np.float32)[:, None]
        convex = 1.0 + (convex - 1.0) * shell
    out[m] = light * gain * convex


def _object_compiled(out, s: _ObjectShape, *, method, albedo, pre_post, thickness, distance, as_thickness) -> None:
    """``_object_reference`` on the compiled backend: ``core.optics._kernels.energy_object`` at the
    pixels of the box, without gathering them (the thickness's logarithm, whose NumPy
    implementation differs in the last bit from the kernel's, taken in NumPy on the box); the
    same float32 and float64 operations in the same order (equal to the bit)."""
    c = np.ascontiguousarray
    mb = c(s.m[s.box])
    y0, x0 = s.box[0].start, s.box[1].start
    # An absent table is passed empty (0 rows: the kernel reads 1); the entry's columns and the
    # convex gain's rows are both ALBEDO.
    none = np.zeros((0, 2), np.float64)
    nodes = np.zeros(2, np.float64)
    albedos = _nodes(ALBEDO)
    entry, views, _ = _entry_table(method) or (none, nodes, None)
    convex, _, curvatures = _convex_table(method) or (none, None, nodes)
    above = below = none
    slab_albedos, logs = nodes, nodes
    x = np.zeros((1, 1), np.float64)
    lt = np.zeros((1, 1, 3), np.float64)
    if s.finite:
        above, below, slab_albedos, logs = _slab_tables(method)
        x = np.zeros(mb.shape, np.float64)  # read on the whole box below
        least = 2.0 / (CHORD_CAP * distance)
        largest = c(s.largest)
        backend.run_kernel(
            _kernels().energy_thickness,
            mb,
            y0,
            x0,
            _float_frame(thickness),
            as_thickness,
            distance,
            least,
            largest,
            x,
        )
        lt = _log_thickness(x[..., None] / s.ell)  # slab_factors' read of the thickness
    unseen = np.zeros(3, np.float32) if s.unseen is None else s.unseen.astype(np.float32)
    mean = [c(v, np.float32) for v in s.mean]
    backend.run_kernel(
        _kernels().energy_object, out, c(albedo, np.float32), y0, x0, mb, bool(pre_post), c(s.mu, np.float32), *mean,
        c(s.ell, np.float64), c(s.largest, np.float32), albedos, entry, views, convex, curvatures, s.finite, x, lt,
        above, below, slab_albedos, logs, unseen, s.unseen is not None,
    )  # fmt: skip
