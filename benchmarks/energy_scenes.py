"""Scenes outside the fidelity suite, to check that a change judged on the suite is not fitted to
it: built the suite's way (``benchmarks/fidelity/scenes.py``) and scored by the same runner.

    nice -n 10 .venv/bin/python -m benchmarks.fidelity.references --scenes-module benchmarks.energy_scenes \\
        --store benchmarks/energy_references
    nice -n 10 .venv/bin/python -m benchmarks.fidelity.run --scenes-module benchmarks.energy_scenes \\
        --store benchmarks/energy_references --out benchmarks/results/fidelity_energy_scenes.json \\
        --table docs/fidelity_energy_scenes.md --grid docs/images/fidelity_energy_scenes.png

| scene | geometry | light | material (method) |
|---|---|---|---|
| skin_ball_area | 10 cm sphere on a floor | small area light from the front-right | skin (Random Walk), 8 mm red |
| wax_cylinder_spot | standing cylinder, 10 cm across | spot from above-left, shadow bar | wax (Legacy), 5 mm red |
| jade_torus_world | torus | grey world and a weak sun from above | jade (Random Walk (Skin)), 6 mm green |
"""

from __future__ import annotations

import math

from benchmarks import scene_kit as kit
from benchmarks.fidelity import scenes as suite
from benchmarks.fidelity.scenes import SuiteScene


def skin_ball_area():
    """A 10 cm skin sphere on a floor, lit by a small area light from the front-right; Random
    Walk, 8 mm red mean free path."""
    scene = kit.reset_scene()
    kit.add_object(
        scene,
        "Ball",
        kit.uv_sphere_mesh("Ball", 0.05, segments=48, rings=24),
        location=(0, 0, 0.05),
        material=kit.skin(scale=0.008),
    )
    kit.floor(scene)
    kit.add_camera(scene, (0.05, -0.35, 0.12), (0.0, 0.0, 0.05), lens=50.0)
    kit.add_light(scene, "Key", "AREA", (0.35, -0.3, 0.3), (0.0, 0.0, 0.05), 15.0, size=0.03)
    return scene


def wax_cylinder_spot():
    """A standing wax cylinder (10 cm across, 12 cm tall) under a spot from above-left, a bar
    casting a hard shadow across it; Random Walk (Legacy), 5 mm red."""
    scene = kit.reset_scene()
    cyl = kit.add_object(
        scene,
        "Candle",
        kit.cylinder_mesh("Candle", 0.05, 0.12, rings=8),
        material=kit.wax(method="RANDOM_WALK_LEGACY", scale=0.06),
    )
    kit.add_subsurf(cyl, 1)
    kit.floor(scene)
    kit.shadow_bar(scene, (-0.1, -0.15, 0.275), size=(0.006, 0.5, 0.006), rotation=(0.0, 0.0, math.radians(-20)))
    kit.add_camera(scene, (0.0, -0.4, 0.2), (0.0, 0.0, 0.06), lens=50.0)
    kit.add_light(
        scene, "Key", "SPOT", (-0.2, -0.25, 0.45), (0.0, 0.0, 0.06), 12.0, shadow_soft_size=0.002, spot_size=1.0
    )
    return scene


def jade_torus_world():
    """A jade torus (14 cm across, 2.5 cm tube) on a floor under a grey world and a weak sun from
    above; Random Walk (Skin), 6 mm green."""
    scene = kit.reset_scene(world_color=(0.45, 0.45, 0.5))
    jade = kit.jade(scale=0.006)
    for node in jade.node_tree.nodes:
        if node.type == "BSDF_PRINCIPLED":
            from sss_lab.blender import compat

            node.subsurface_method = compat.subsurface_method_item("RANDOM_WALK_SKIN")
    kit.add_object(scene, "Torus", kit.torus("Torus", 0.045, 0.025), location=(0.0, 0.0, 0.025), material=jade)
    kit.floor(scene)
    kit.add_camera(scene, (0.0, -0.3, 0.22), (0.0, 0.0, 0.02), lens=50.0)
    kit.add_light(scene, "Sun", "SUN", (0.2, -0.1, 1.0), (0.0, 0.0, 0.0), 1.0, angle=math.radians(2.0))
    return scene


SCENES: dict[str, SuiteScene] = {
    s.name: s
    for s in (
        SuiteScene(f.__name__, "diffusion", f, (f.__doc__ or "").split("\n\n")[0].strip().replace("\n    ", " "))
        for f in (skin_ball_area, wax_cylinder_spot, jade_torus_world)
    )
}

assert set(SCENES).isdisjoint(suite.SCENES)
