"""The fidelity suite's scenes, built by script.

Each entry of ``SCENES`` is a ``SuiteScene``: a builder that makes the scene in the current
Blender session (from factory settings) and a ``kind`` that says what the scene tests:
``"diffusion"`` (light enters where the camera sees it lit: SSSS and Burley's case) or
``"backlit"`` (the camera sees light that went through the object: STA's case). The runner
(``benchmarks/fidelity/run.py``) treats every scene the same way, so a scene built elsewhere
with the same conventions (a module with its own ``SCENES``) is scored identically.

Conventions (those of ``sample_blends/build_scenes.py``; the objects, materials and lights come
from the benchmarks' scene toolkit, ``benchmarks/scene_kit.py``):
metres; Principled BSDF materials with every subsurface input set; Cycles CPU, 128 x 128,
adaptive sampling and denoising off; lights invisible to the camera. The builder stops before
pass indices and the thickness bake: ``prepare`` adds them after the scene's fingerprint is
taken, so that the fingerprint covers exactly what the Cycles reference depends on.

What the suite spans (the "mfp" is the longest channel's length as the material's subsurface
method reads it, Radius x Scale, divided by 4 pi for Christensen-Burley and Random Walk
(Legacy), in pixels at the depth of the object's origin; the Burley footprint is about 16 times
that divided by the albedo scaling):

| scene | geometry | light | material (method) | mfp |
|---|---|---|---|---|
| sphere_front_skin | sphere | sun from the front, hard shadow bar | skin (Random Walk Skin) | 1.6 px |
| slab_grazing_marble | 8-vertex slab | grazing sun | marble (Random Walk) | 7.7 px |
| fins_backlit_jade | four 8-vertex fins, 2-24 mm | sun from behind | jade (Random Walk) | 1.7 px |
| torus_spot_wax | torus | spot, hard shadow bar | wax (Random Walk) | 12 px |
| head_area_skin | head-like shape | small area light (hard shadow) | skin (Random Walk) | 4.1 px |
| lowpoly_milk_lights | low-poly icosphere and box | three coloured lights | milk (Christensen-Burley) | 3.7-4.0 px |
| bowl_concave_wax | concave bowl | spot from above | wax (Random Walk Legacy) | 2.9 px |
| world_marble | sphere and cube | bright world only | marble (Random Walk) | 3.9-4.0 px |
| skin_before_marble | head in front of a marble ball | spot | skin and marble (Random Walk) | 3.3-3.9 px |
| jade_behind_pillar | ball behind a non-SSS pillar | area light | jade (Random Walk) | 2.7-3.0 px |
| tiny_mfp_skin | three far spheres | sun | skin (Random Walk Skin) | 0.4-0.5 px |
| huge_mfp_wax | close-up block | spot, hard edge | wax (Random Walk) | 80 px |
| ear_backlit_skin | ear-like lobe | sun from behind | skin (Random Walk) | 7.1 px |
| candle_backlit_wax | thin candle and sphere | spot from behind | wax (Random Walk) | 6.6-6.7 px |
| edge_longmfp_milk | block, hard shadow edge on its top | small sun | milk (Random Walk) | 11 px |
| head_world_area | head-like shape | bright world, small area light | skin (Random Walk) | 4.2 px |
| wax_spot_cone | slab | narrow spot, hard cone edge | wax (Random Walk) | 6.7 px |

A third of the scenes is held out of every fit and tuning decision (``held_out``: chosen by the
name's hash, before any result); the runner and ``benchmarks/fit.py`` report them apart.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass

from benchmarks import scene_kit as kit

#: The suite's image size (the stored references are rendered at it).
RESOLUTION = (128, 128)
#: The thickness AOV the techniques read.
THICKNESS_AOV = "Thickness"
#: Rays per vertex for the suite's thickness bake (as the sample scenes).
THICKNESS_SAMPLES = 64
KINDS = ("diffusion", "backlit")


def held_out(name: str) -> bool:
    """True for the scenes kept out of every fit and tuning decision (a third of the suite, fixed
    by the scene's name alone, before any result: SHA-256 of the name, modulo 3, is 2). The runner
    and ``benchmarks/fit.py`` report them apart; ``benchmarks/auto.py --write-model`` learns the
    shipped model without them."""
    return int(hashlib.sha256(name.encode()).hexdigest(), 16) % 3 == 2


@dataclass(frozen=True)
class SuiteScene:
    name: str
    kind: str
    build: Callable[[], object]
    description: str

    @property
    def held_out(self) -> bool:
        return held_out(self.name)


# --- Scenes ----------------------------------------------------------------------------------


def sphere_front_skin():
    """A 12 cm skin sphere lit from the front-left by a small sun; a bar draws a hard shadow line
    across it. Skin of Jensen et al. (3.7 mm red) with the Random Walk (Skin) method."""
    scene = kit.reset_scene()
    kit.add_object(
        scene,
        "Ball",
        kit.uv_sphere_mesh("Ball", 0.06, segments=48, rings=24),
        material=kit.skin(method="RANDOM_WALK_SKIN"),
    )
    kit.floor(scene, z=-0.06)
    kit.shadow_bar(scene, (0.0, -0.2, 0.08), rotation=(0.0, math.radians(30), 0.0))
    kit.add_camera(scene, (0.0, -0.4, 0.05), (0.0, 0.0, 0.0), lens=50.0)
    kit.add_light(scene, "Key", "SUN", (-0.5, -1.0, 0.6), (0.0, 0.0, 0.0), 3.0, angle=math.radians(0.5))
    kit.add_light(scene, "Fill", "AREA", (0.6, -0.5, 0.2), (0.0, 0.0, 0.0), 0.3, size=0.4)
    return scene


def slab_grazing_marble():
    """A 14 x 10 x 3 cm marble slab made of one 8-vertex box (low-poly), lit at a grazing angle
    by a small sun (12 degrees above its face) and a little fill."""
    scene = kit.reset_scene()
    slab = kit.add_object(
        scene,
        "Slab",
        kit.box_mesh("Slab", (0.14, 0.03, 0.10)),
        rotation=(0.0, 0.0, math.radians(15)),
        material=kit.marble(scale=0.017),
        smooth=False,
    )
    del slab
    kit.floor(scene, z=-0.05)
    kit.add_camera(scene, (0.05, -0.38, 0.08), (0.0, 0.0, 0.0), lens=50.0)
    kit.add_light(scene, "Key", "SUN", (1.0, -0.21, 0.15), (0.0, 0.0, 0.0), 5.0, angle=math.radians(1.0))
    kit.add_light(scene, "Fill", "AREA", (-0.4, -0.6, 0.3), (0.0, 0.0, 0.0), 0.4, size=0.5)
    return scene


def fins_backlit_jade():
    """Four jade fins (each one 8-vertex box, 5 x 9 cm) 2, 5, 12 and 24 mm thick, side by side,
    lit from behind by a sun; the camera sees their unlit faces. Jade with a 4 mm green mean free
    path (Random Walk)."""
    scene = kit.reset_scene(world_color=(0.01, 0.01, 0.012))
    jade = kit.jade()
    for i, t in enumerate((0.002, 0.005, 0.012, 0.024)):
        kit.add_object(
            scene,
            f"Fin {i + 1}",
            kit.box_mesh(f"Fin {i + 1}", (0.05, t, 0.09)),
            location=(-0.09 + 0.06 * i, 0.0, 0.0),
            material=jade,
            smooth=False,
        )
    kit.add_camera(scene, (0.0, -0.42, 0.02), (0.0, 0.0, 0.0), lens=50.0)
    kit.add_light(scene, "Back", "SUN", (0.15, 1.0, 0.3), (0.0, 0.0, 0.0), 4.0, angle=math.radians(1.0))
    kit.add_light(scene, "Fill", "AREA", (-0.3, -0.6, 0.2), (0.0, 0.0, 0.0), 0.1, size=0.3)
    return scene


def torus_spot_wax():
    """A wax torus (16 cm across, 3 cm tube) lying on a floor under a small spot light, with a bar
    casting a hard shadow line across it; long mean free path (3 cm red, Random Walk)."""
    return torus_spot(lambda: kit.wax(scale=0.03))


def torus_spot(material):
    """``torus_spot_wax``'s torus, floor, shadow bar, camera and lights around the material
    ``material()`` makes (called after the factory reset): the set-up other scene modules share."""
    scene = kit.reset_scene()
    torus = kit.torus("Torus", 0.065, 0.03)
    kit.add_object(scene, "Torus", torus, location=(0.0, 0.0, 0.03), material=material())
    kit.floor(scene)
    kit.shadow_bar(scene, (-0.07, -0.1, 0.2), size=(0.006, 0.5, 0.006), rotation=(0.0, 0.0, math.radians(20)))
    kit.add_camera(scene, (0.0, -0.38, 0.28), (0.0, 0.0, 0.02), lens=50.0)
    kit.add_light(
        scene, "Key", "SPOT", (-0.25, -0.25, 0.45), (0.0, 0.0, 0.03), 15.0, shadow_soft_size=0.002, spot_size=1.0
    )
    kit.add_light(scene, "Fill", "AREA", (0.5, -0.3, 0.3), (0.0, 0.0, 0.0), 0.5, size=0.5)
    return scene


def head_area_skin():
    """The head-like shape (16 x 19 x 22 cm) lit by a small area light from the side (hard
    shadows of the nose and brow); skin with a 1.2 cm red mean free path (Random Walk)."""
    return head_area(lambda: kit.skin(scale=0.012))


def head_area(material):
    """``head_area_skin``'s head, wall, camera and lights around the material ``material()`` makes
    (called after the factory reset)."""
    scene = kit.reset_scene()
    head = kit.add_object(scene, "Head", kit.head_mesh("Head"), material=material())
    kit.add_subsurf(head, 1)
    kit.wall(scene, 0.3, z=0.0)
    kit.add_camera(scene, (0.15, -0.6, 0.05), (0.0, 0.0, 0.0), lens=60.0)
    kit.add_light(scene, "Key", "AREA", (-0.5, -0.35, 0.25), (0.0, 0.0, 0.0), 20.0, size=0.02)
    kit.add_light(scene, "Fill", "AREA", (0.6, -0.6, 0.1), (0.0, 0.0, 0.0), 0.4, size=0.4)
    return scene


def lowpoly_milk_lights():
    """A low-poly milk icosphere (42 vertices, flat shaded) and an 8-vertex milk box, lit by three
    coloured lights (warm sun, blue point, white spot). Christensen-Burley method, whose radius
    Cycles divides by 4 pi, so the scale is 12 cm (about 1 cm as a profile d)."""
    scene = kit.reset_scene()
    milk = kit.milk(method="BURLEY", scale=0.12)
    kit.add_object(
        scene, "Ico", kit.icosphere("Ico", 0.06, 1), location=(-0.05, 0.0, 0.06), material=milk, smooth=False
    )
    kit.add_object(
        scene,
        "Box",
        kit.box_mesh("Box", (0.07, 0.07, 0.07)),
        location=(0.07, 0.03, 0.035),
        rotation=(0.0, 0.0, math.radians(35)),
        material=milk,
        smooth=False,
    )
    kit.floor(scene, color=(0.2, 0.2, 0.2))
    kit.add_camera(scene, (0.0, -0.4, 0.2), (0.01, 0.0, 0.05), lens=50.0)
    kit.add_light(scene, "Warm", "SUN", (-0.6, -0.5, 0.5), (0, 0, 0), 2.5, color=(1.0, 0.8, 0.6), angle=math.radians(1))
    kit.add_light(
        scene, "Cool", "POINT", (0.3, -0.2, 0.1), (0, 0, 0), 3.0, color=(0.5, 0.6, 1.0), shadow_soft_size=0.005
    )
    kit.add_light(scene, "Top", "SPOT", (0.05, 0.0, 0.5), (0.0, 0.0, 0.0), 10.0, shadow_soft_size=0.003, spot_size=0.6)
    return scene


def bowl_concave_wax():
    """A wax bowl (18 cm across, 1.5 cm walls) seen from above at an angle, so that its concave
    inside faces the camera; a spot from above lights the inside and the rim shadows part of
    it. Random Walk (Legacy), whose radius Cycles divides by 4 pi: 10 cm scale, about 8 mm."""
    scene = kit.reset_scene()
    bowl = kit.add_object(
        scene,
        "Bowl",
        kit.bowl("Bowl", 0.09, 0.015),
        location=(0.0, 0.0, 0.09),
        material=kit.wax(method="RANDOM_WALK_LEGACY", scale=0.1),
    )
    kit.add_subsurf(bowl, 1)
    kit.floor(scene)
    kit.add_camera(scene, (0.0, -0.35, 0.42), (0.0, 0.0, 0.06), lens=50.0)
    kit.add_light(scene, "Key", "SPOT", (0.25, 0.1, 0.5), (0.0, 0.0, 0.06), 12.0, shadow_soft_size=0.003, spot_size=1.0)
    kit.add_light(scene, "Fill", "AREA", (-0.4, -0.5, 0.4), (0.0, 0.0, 0.0), 0.4, size=0.5)
    return scene


def world_marble():
    """A marble sphere (10 cm) and a bevelled marble cube (7 cm) under a bright uniform world and
    no lamp: soft light from everywhere, the occlusion between them the only contrast."""
    scene = kit.reset_scene(world_color=(0.9, 0.9, 0.95))
    marble = kit.marble()
    kit.add_object(
        scene,
        "Ball",
        kit.uv_sphere_mesh("Ball", 0.05, segments=48, rings=24),
        location=(-0.045, 0.0, 0.05),
        material=marble,
    )
    cube = kit.add_object(
        scene,
        "Cube",
        kit.box_mesh("Cube", (0.07, 0.07, 0.07), cuts=3),
        location=(0.06, -0.01, 0.035),
        rotation=(0.0, 0.0, math.radians(25)),
        material=marble,
        smooth=False,
    )
    bevel = cube.modifiers.new("Bevel", "BEVEL")
    bevel.width, bevel.segments = 0.005, 3
    kit.floor(scene, color=(0.35, 0.35, 0.35))
    kit.add_camera(scene, (0.0, -0.38, 0.12), (0.005, 0.0, 0.04), lens=50.0)
    return scene


def skin_before_marble():
    """A small skin head (12 x 14 x 17 cm) in front of a marble ball (14 cm) 20 cm behind it, both
    lit by a spot from the front-left that casts the head's shadow on the ball: subsurface objects
    overlapping at different depths (Random Walk)."""
    scene = kit.reset_scene()
    head = kit.add_object(
        scene,
        "Head",
        kit.head_mesh("Head", (0.12, 0.14, 0.17)),
        location=(-0.03, -0.1, 0.0),
        material=kit.skin(scale=0.01),
    )
    kit.add_subsurf(head, 1)
    kit.add_object(
        scene,
        "Ball",
        kit.uv_sphere_mesh("Ball", 0.07, segments=48, rings=24),
        location=(0.06, 0.12, 0.0),
        material=kit.marble(scale=0.012),
    )
    kit.wall(scene, 0.4, z=0.2)
    kit.add_camera(scene, (0.0, -0.65, 0.04), (0.01, 0.0, 0.0), lens=60.0)
    kit.add_light(
        scene, "Key", "SPOT", (-0.4, -0.45, 0.25), (0.0, 0.0, 0.0), 25.0, shadow_soft_size=0.003, spot_size=1.0
    )
    kit.add_light(scene, "Fill", "AREA", (0.5, -0.5, 0.2), (0.0, 0.0, 0.0), 0.4, size=0.4)
    return scene


def jade_behind_pillar():
    """A jade ball (11 cm) half hidden behind a grey pillar (no SSS) in front of it, and a jade
    block beside it on a floor: subsurface objects behind another object, lit by a small area
    light whose hard shadow of the pillar falls across the ball."""
    return jade_ball_and_block(lambda: kit.jade(scale=0.008), pillar=True)


def jade_ball_and_block(material, *, pillar: bool):
    """``jade_behind_pillar``'s ball, block, floor, camera and lights around the material
    ``material()`` makes (called after the factory reset), with its pillar or without."""
    scene = kit.reset_scene()
    jade = material()
    kit.add_object(
        scene,
        "Ball",
        kit.uv_sphere_mesh("Ball", 0.055, segments=48, rings=24),
        location=(0.0, 0.05, 0.055),
        material=jade,
    )
    kit.add_object(
        scene,
        "Block",
        kit.box_mesh("Block", (0.05, 0.05, 0.08), cuts=3),
        location=(0.1, 0.1, 0.04),
        material=jade,
        smooth=False,
    )
    if pillar:
        kit.add_object(
            scene,
            "Pillar",
            kit.cylinder_mesh("Pillar", 0.015, 0.2, rings=4),
            location=(-0.02, -0.07, 0.0),
            material=kit.plain_material("Pillar", (0.4, 0.4, 0.4), roughness=0.4),
        )
    kit.floor(scene)
    kit.add_camera(scene, (0.0, -0.42, 0.12), (0.02, 0.03, 0.05), lens=50.0)
    kit.add_light(scene, "Key", "AREA", (-0.3, -0.45, 0.3), (0.0, 0.0, 0.05), 12.0, size=0.015)
    kit.add_light(scene, "Fill", "AREA", (0.5, -0.3, 0.3), (0.0, 0.0, 0.0), 0.4, size=0.5)
    return scene


def tiny_mfp_skin():
    """Three skin spheres (8 cm) 1.4 m from the camera: the mean free path (3.7 mm red) is below
    half a pixel, so SSS barely shows; Random Walk (Skin). A technique must not make it worse."""
    scene = kit.reset_scene()
    skin = kit.skin(method="RANDOM_WALK_SKIN")
    for i, x in enumerate((-0.12, 0.0, 0.12)):
        kit.add_object(
            scene,
            f"Ball {i + 1}",
            kit.uv_sphere_mesh(f"Ball {i + 1}", 0.04),
            location=(x, 0.05 * i, 0.04),
            material=skin,
        )
    kit.floor(scene)
    kit.add_camera(scene, (0.0, -1.4, 0.3), (0.0, 0.05, 0.04), lens=50.0)
    kit.add_light(scene, "Key", "SUN", (-0.6, -0.8, 0.7), (0.0, 0.0, 0.0), 3.0, angle=math.radians(1.0))
    return scene


def huge_mfp_wax():
    """A close-up (100 mm lens) of a bevelled wax block, 8 cm wide, with an 8 cm red mean free
    path (about 90 px), half in the hard-edged light of a spot: the light spreads across the
    whole block (Random Walk)."""
    scene = kit.reset_scene()
    block = kit.add_object(
        scene,
        "Block",
        kit.box_mesh("Block", (0.08, 0.06, 0.08), cuts=4),
        location=(0.0, 0.0, 0.04),
        rotation=(0.0, 0.0, math.radians(20)),
        material=kit.wax(scale=0.08),
        smooth=False,
    )
    bevel = block.modifiers.new("Bevel", "BEVEL")
    bevel.width, bevel.segments = 0.006, 3
    kit.floor(scene)
    # A plate whose edge crosses the middle of the spot's beam: half the block in hard shadow.
    kit.shadow_bar(scene, (0.05, -0.1, 0.27), size=(0.2, 0.2, 0.004), rotation=(0.0, 0.0, math.radians(20)))
    kit.add_camera(scene, (0.0, -0.34, 0.14), (0.0, 0.0, 0.04), lens=100.0)
    kit.add_light(
        scene, "Key", "SPOT", (-0.1, -0.2, 0.5), (0.0, 0.0, 0.04), 25.0, shadow_soft_size=0.002, spot_size=0.8
    )
    kit.add_light(scene, "Fill", "AREA", (0.5, -0.4, 0.2), (0.0, 0.0, 0.0), 0.3, size=0.5)
    return scene


def ear_backlit_skin():
    """The sample scenes' ear-like lobe (7 x 12 cm, 1.8 cm thick in the middle, thin at the rim)
    lit from behind by a sun; skin with a 1.2 cm red mean free path (Random Walk)."""
    scene = kit.reset_scene(world_color=(0.015, 0.015, 0.02))
    ear = kit.add_object(
        scene, "Ear", kit.ear_mesh("Ear"), rotation=(0.0, 0.0, math.radians(12)), material=kit.skin(scale=0.012)
    )
    kit.add_subsurf(ear, 1)
    kit.add_camera(scene, (0.0, -0.3, 0.01), (0.0, 0.0, 0.0), lens=50.0)
    kit.add_light(scene, "Back", "SUN", (0.3, 1.0, 0.35), (0.0, 0.0, 0.0), 4.0, angle=math.radians(1.0))
    kit.add_light(scene, "Fill", "AREA", (-0.4, -0.5, 0.2), (0.0, 0.0, 0.0), 0.15, size=0.3)
    return scene


def candle_backlit_wax():
    """A thin wax candle (2.4 cm across) and a wax ball (5 cm) lit from behind by a spot, a little
    fill from the front; wax with a 1.5 cm red mean free path (Random Walk)."""
    scene = kit.reset_scene(world_color=(0.01, 0.01, 0.012))
    wax = kit.wax(scale=0.015)
    candle = kit.add_object(
        scene, "Candle", kit.cylinder_mesh("Candle", 0.012, 0.14, rings=10), location=(-0.03, 0.0, 0.0)
    )
    candle.data.materials.append(wax)
    kit.add_subsurf(candle, 1)
    kit.add_object(scene, "Ball", kit.uv_sphere_mesh("Ball", 0.025), location=(0.04, 0.0, 0.04), material=wax)
    kit.add_camera(scene, (0.0, -0.4, 0.07), (0.0, 0.0, 0.06), lens=50.0)
    kit.add_light(
        scene, "Back", "SPOT", (0.05, 0.4, 0.12), (0.0, 0.0, 0.06), 20.0, shadow_soft_size=0.01, spot_size=1.2
    )
    kit.add_light(scene, "Fill", "AREA", (-0.4, -0.5, 0.2), (0.0, 0.0, 0.0), 0.1, size=0.3)
    return scene


def edge_longmfp_milk():
    """A milk block (12 x 12 x 6 cm) under a small sun, a bar casting a hard shadow edge across its
    top face; a long mean free path (2.4 cm red, Random Walk): light carried far into the shadow."""
    scene = kit.reset_scene()
    kit.add_object(
        scene,
        "Block",
        kit.box_mesh("Block", (0.12, 0.12, 0.06), cuts=6),
        location=(0.0, 0.0, 0.03),
        material=kit.milk(scale=0.024),
        smooth=False,
    )
    kit.floor(scene)
    kit.shadow_bar(scene, (0.07, 0.0, 0.2), size=(0.012, 0.5, 0.012), rotation=(0.0, 0.0, math.radians(10)))
    kit.add_camera(scene, (0.0, -0.3, 0.3), (0.0, 0.0, 0.03), lens=50.0)
    kit.add_light(scene, "Sun", "SUN", (0.3, -0.2, 0.6), (0.0, 0.0, 0.0), 3.0, angle=math.radians(0.5))
    return scene


def head_world_area():
    """The head-like shape (16 x 19 x 22 cm) under a bright world and a small area light from the
    side: the face lit softly from everywhere, with the key light's hard shadows (skin, 1.2 cm red,
    Random Walk)."""
    scene = kit.reset_scene(world_color=(0.45, 0.47, 0.5))
    head = kit.add_object(scene, "Head", kit.head_mesh("Head"), material=kit.skin(scale=0.012))
    kit.add_subsurf(head, 1)
    kit.floor(scene, z=-0.12)
    kit.add_camera(scene, (-0.12, -0.6, 0.06), (0.0, 0.0, 0.0), lens=60.0)
    kit.add_light(scene, "Key", "AREA", (0.5, -0.3, 0.2), (0.0, 0.0, 0.0), 15.0, size=0.02)
    return scene


def wax_spot_cone():
    """A wax slab (16 x 12 x 4 cm) lit by a narrow spot whose cone ends in a hard circle on its top
    face (no blend): the light carried out of the cone under the surface (wax, 1.6 cm red,
    Random Walk)."""
    scene = kit.reset_scene()
    kit.add_object(
        scene,
        "Slab",
        kit.box_mesh("Slab", (0.16, 0.12, 0.04), cuts=6),
        location=(0.0, 0.0, 0.02),
        material=kit.wax(scale=0.016),
        smooth=False,
    )
    kit.floor(scene)
    kit.add_camera(scene, (0.0, -0.32, 0.3), (0.0, 0.0, 0.02), lens=50.0)
    kit.add_light(
        scene,
        "Key",
        "SPOT",
        (0.02, 0.0, 0.3),
        (0.02, 0.0, 0.04),
        8.0,
        shadow_soft_size=0.001,
        spot_size=math.radians(14),
        spot_blend=0.0,
    )
    kit.add_light(scene, "Fill", "AREA", (-0.4, -0.4, 0.4), (0.0, 0.0, 0.0), 1.5, size=0.5)
    return scene


SCENES: dict[str, SuiteScene] = {
    s.name: s
    for s in (
        SuiteScene(f.__name__, kind, f, (f.__doc__ or "").split("\n\n")[0].strip().replace("\n    ", " "))
        for f, kind in (
            (sphere_front_skin, "diffusion"),
            (slab_grazing_marble, "diffusion"),
            (fins_backlit_jade, "backlit"),
            (torus_spot_wax, "diffusion"),
            (head_area_skin, "diffusion"),
            (lowpoly_milk_lights, "diffusion"),
            (bowl_concave_wax, "diffusion"),
            (world_marble, "diffusion"),
            (skin_before_marble, "diffusion"),
            (jade_behind_pillar, "diffusion"),
            (tiny_mfp_skin, "diffusion"),
            (huge_mfp_wax, "diffusion"),
            (ear_backlit_skin, "backlit"),
            (candle_backlit_wax, "backlit"),
            (edge_longmfp_milk, "diffusion"),
            (head_world_area, "diffusion"),
            (wax_spot_cone, "diffusion"),
        )
    )
}


#: Frame B of every scene (``frame_b``): the camera turned this many degrees about the vertical
#: axis through the subsurface objects' centre and moved this share closer to it; the lights
#: turned the other way. The same asset seen and lit otherwise, for a fit made on frame A.
FRAME_B_CAMERA_TURN = 20.0
FRAME_B_LIGHT_TURN = -15.0
FRAME_B_DOLLY = 0.9


def frame_b(scene):
    """Move ``scene``'s camera and lights to frame B (the constants above); returns ``scene``.

    The asset (geometry, materials, world, floor and walls) stays; only the view and the lighting
    change, so that a fit made on frame A can be scored on B against B's own reference."""
    import bpy
    from mathutils import Matrix, Vector

    bpy.context.view_layer.update()  # the builders set locations and rotations: make matrix_world current
    centres = [
        o.matrix_world @ (sum((Vector(c) for c in o.bound_box), Vector()) / 8.0) for o in subsurface_objects(scene)
    ]
    centre = sum(centres, Vector()) / max(len(centres), 1)

    def turn(degrees):
        return Matrix.Translation(centre) @ Matrix.Rotation(math.radians(degrees), 4, "Z") @ Matrix.Translation(-centre)

    for obj in scene.objects:
        if obj.type == "LIGHT":
            obj.matrix_world = turn(FRAME_B_LIGHT_TURN) @ obj.matrix_world
        elif obj.type == "CAMERA":
            m = turn(FRAME_B_CAMERA_TURN) @ obj.matrix_world
            m.translation = centre + (m.translation - centre) * FRAME_B_DOLLY
            obj.matrix_world = m
    bpy.context.view_layer.update()
    return scene


def _frame_b_builder(build):
    return lambda: frame_b(build())


#: Frame B of every scene, the same names and kinds (``frame_b``). Its references are stored apart
#: (``references.STORE_B``); ``benchmarks/fit.py`` scores on it the fits made on frame A.
SCENES_B: dict[str, SuiteScene] = {
    name: SuiteScene(name, s.kind, _frame_b_builder(s.build), f"{s.description} Frame B: camera and lights moved.")
    for name, s in SCENES.items()
}


def build(name: str, scenes: dict | None = None):
    """Build scene ``name`` (of ``scenes``, default the suite's) in the current session, at the
    suite's resolution; returns the bpy scene (not yet prepared)."""
    table = SCENES if scenes is None else scenes
    if name not in table:
        raise ValueError(f"unknown fidelity scene {name!r}; expected one of: {', '.join(table)}")
    scene = table[name].build()
    scene.render.resolution_x, scene.render.resolution_y = RESOLUTION
    scene.render.resolution_percentage = 100
    return scene


def subsurface_objects(scene) -> list:
    """Mesh objects carrying a material that scatters, in name order."""
    return kit.sss_objects(scene)


def prepare(scene) -> None:
    """Pass indices (the sample scenes' convention: subsurface materials 1, 2, ... in name order,
    other materials 0, mesh objects 1, 2, ...) and the thickness AOV on the view layer."""
    materials = {slot.material.name: slot.material for o in scene.objects for slot in o.material_slots if slot.material}
    index = 0
    for name in sorted(materials):
        mat = materials[name]
        if kit.scatters(mat):
            index += 1
            mat.pass_index = index
        else:
            mat.pass_index = 0
    for i, obj in enumerate(sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name), start=1):
        obj.pass_index = i
    layer = scene.view_layers[0]
    if THICKNESS_AOV not in layer.aovs:
        aov = layer.aovs.add()
        aov.name, aov.type = THICKNESS_AOV, "VALUE"


def bake(scene, source: str | None = None) -> list:
    """The thickness bake of the subsurface meshes with the bake's defaults (attribute target,
    ``THICKNESS_SAMPLES`` rays; ``source`` the bake's, its default by default); returns the bake results.
    Done after the fingerprint: the map changes what STA reads, not what Cycles renders."""
    from sss_lab.blender.bake import bake_thickness
    from sss_lab.core.scene.thickness import BakeSettings

    settings = BakeSettings(target="attribute", samples=THICKNESS_SAMPLES, attribute_name=THICKNESS_AOV, source=source)
    return bake_thickness(scene, subsurface_objects(scene), settings, log=None)
