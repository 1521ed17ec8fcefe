"""Every technique gives the same SSS term for a scene and its copy scaled by 10^-3 and 10^3 (every
length: depth, positions, camera and light placement, the material's Subsurface Scale and bake
distance), on the analytic plane-and-spheres scene of core/study/synthetic.py. No length inside a
technique may be absolute rather than relative to the scene or the mean free path.

Tolerance: 1e-4 of the term's L1 norm. The scaled passes are float32 values k times the original
ones, rounded again (relative 6e-8 each); measured here the terms move by 2e-6 to 3e-6 at most
(SSSS, Burley, combined) and 1e-7 (STA), far below the tolerance; an absolute length in a kernel
moves them by far more (a profile cut at a fixed 1e-8 scene units, say, zeroes a scene in
micrometres)."""

import dataclasses

import numpy as np
import pytest

from sss_lab.core.pipeline.apply import apply
from sss_lab.core.scene.exr import Passes
from sss_lab.core.study.synthetic import sphere_scene
from sss_lab.core.techniques.registry import TECHNIQUES


def _scaled(arrays, scene, k):
    a = dict(arrays)
    depth = a["Depth"]
    a["Depth"] = np.where(depth >= 1e9, depth, depth * k).astype(np.float32)
    a["Position"] = (a["Position"] * k).astype(np.float32)

    def moved(matrix):
        m = np.array(matrix, dtype=np.float64).reshape(4, 4)
        m[:3, 3] *= k
        return tuple(m.ravel())

    cam = scene.camera
    cam = dataclasses.replace(
        cam,
        matrix_world=moved(cam.matrix_world),
        clip_start=cam.clip_start * k,
        clip_end=cam.clip_end * k,
        ortho_scale=cam.ortho_scale * k,
    )
    lights = tuple(
        dataclasses.replace(light, matrix_world=moved(light.matrix_world), radius=light.radius * k, size=light.size * k)
        for light in scene.lights
    )
    materials = tuple(
        dataclasses.replace(m, subsurface_scale=m.subsurface_scale * k, thickness_distance=m.thickness_distance * k)
        for m in scene.materials
    )
    return Passes(a), dataclasses.replace(scene, camera=cam, lights=lights, materials=materials)


@pytest.mark.parametrize("technique", list(TECHNIQUES))
@pytest.mark.parametrize("k", [1e-3, 1e3])
def test_the_sss_term_does_not_depend_on_the_scene_scale(technique, k):
    arrays, scene = sphere_scene(96, 64)
    scene = dataclasses.replace(
        scene, materials=tuple(dataclasses.replace(m, thickness_distance=0.5) for m in scene.materials)
    )
    base = apply(Passes(arrays), scene, technique)[f"SSSLab.{technique}.SSS"]
    passes, scaled = _scaled(arrays, scene, k)
    got = apply(passes, scaled, technique)[f"SSSLab.{technique}.SSS"]
    norm = float(np.abs(base).sum())
    assert norm > 0
    assert float(np.abs(got - base).sum()) <= 1e-4 * norm
