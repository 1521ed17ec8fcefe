"""Three more back-lit scenes, outside the fidelity suite: a check that the combined technique's
light from behind was not tuned to the suite's three (docs/references.md §14).

Built with the suite's conventions (``benchmarks/fidelity/scenes.py``) and scored by the same
runner; their references are stored apart, in ``backlit_extra_references/``::

    nice -n 10 .venv/bin/python -m benchmarks.fidelity.references --scenes-module \\
        benchmarks.fidelity.backlit_extra --store benchmarks/fidelity/backlit_extra_references
    nice -n 10 .venv/bin/python -m benchmarks.fidelity.run --scenes-module benchmarks.fidelity.backlit_extra \\
        --store benchmarks/fidelity/backlit_extra_references --out benchmarks/results/fidelity_backlit_extra.json \\
        --table docs/fidelity_backlit_extra.md --grid docs/images/fidelity_backlit_extra.png

| scene | geometry | light | material (method) |
|---|---|---|---|
| wedge_backlit_milk | wedge 1 to 20 mm thick, 8 x 6 cm, flat face seen | point behind | milk (Random Walk) |
| torus_backlit_marble | ring (3 cm tube) seen at an angle | area behind | marble (Christensen-Burley) |
| fingers_backlit_skin | three cylinders 1.4 to 2.2 cm across | sun behind, fill | skin (Random Walk Skin) |
"""

from __future__ import annotations

import math

from benchmarks import scene_kit as kit

from .scenes import SuiteScene


def _wedge(name, width=0.08, height=0.06, thin=0.001, thick=0.02, nx=24, nz=12):
    """A wedge: the front face (y = 0) flat, the back face at y = thickness, which grows linearly
    from ``thin`` at x = -width/2 to ``thick`` at x = +width/2; a grid of vertices on every face
    so that a per-vertex thickness bake resolves the ramp."""
    import bmesh
    from mathutils import Vector

    def build(bm):
        def t(x):
            return thin + (thick - thin) * (x / width + 0.5)

        xs = [-width / 2 + width * i / nx for i in range(nx + 1)]
        zs = [-height / 2 + height * k / nz for k in range(nz + 1)]
        front = [[bm.verts.new(Vector((x, 0.0, z))) for z in zs] for x in xs]
        back = [[bm.verts.new(Vector((x, t(x), z))) for z in zs] for x in xs]
        for i in range(nx):
            for k in range(nz):
                bm.faces.new((front[i][k], front[i + 1][k], front[i + 1][k + 1], front[i][k + 1]))
                bm.faces.new((back[i][k + 1], back[i + 1][k + 1], back[i + 1][k], back[i][k]))
        for i in range(nx):  # bottom and top
            bm.faces.new((front[i][0], back[i][0], back[i + 1][0], front[i + 1][0]))
            bm.faces.new((front[i + 1][-1], back[i + 1][-1], back[i][-1], front[i][-1]))
        for k in range(nz):  # the thin and the thick end
            bm.faces.new((front[0][k + 1], back[0][k + 1], back[0][k], front[0][k]))
            bm.faces.new((front[-1][k], back[-1][k], back[-1][k + 1], front[-1][k + 1]))
        bmesh.ops.recalc_face_normals(bm, faces=bm.faces[:])

    return kit.new_mesh(name, build)


def wedge_backlit_milk():
    """A milk wedge, 1 mm thick at one end and 20 mm at the other, lit from behind by a point
    light; the camera sees its flat front face: the light through it as a function of thickness
    (Random Walk, 4.8 mm red mean free path)."""
    scene = kit.reset_scene(world_color=(0.01, 0.01, 0.012))
    kit.add_object(scene, "Wedge", _wedge("Wedge"), material=kit.milk(scale=0.0048), smooth=False)
    kit.add_camera(scene, (0.0, -0.3, 0.0), (0.0, 0.0, 0.0), lens=50.0)
    kit.add_light(scene, "Back", "POINT", (0.02, 0.25, 0.04), (0.0, 0.0, 0.0), 20.0, shadow_soft_size=0.01)
    return scene


def torus_backlit_marble():
    """A marble ring (14 cm across, 3 cm tube) tilted towards the camera, lit from behind and
    above by an area light, a dim fill in front; Christensen-Burley with a 10 cm scale (8 mm red
    as the profile's d)."""
    scene = kit.reset_scene(world_color=(0.01, 0.01, 0.012))
    marble = kit.new_material(
        "Marble", (0.83, 0.791, 0.753), radius=(1.0, 0.655, 0.464), scale=0.1, method="BURLEY", ior=1.5, roughness=0.3
    )
    kit.add_object(
        scene, "Ring", kit.torus("Ring", 0.055, 0.015), rotation=(math.radians(70), 0.0, 0.0), material=marble
    )
    kit.add_camera(scene, (0.0, -0.4, 0.05), (0.0, 0.0, 0.0), lens=50.0)
    kit.add_light(scene, "Back", "AREA", (0.05, 0.35, 0.2), (0.0, 0.0, 0.0), 30.0, size=0.1)
    kit.add_light(scene, "Fill", "AREA", (-0.4, -0.5, 0.2), (0.0, 0.0, 0.0), 0.1, size=0.3)
    return scene


def fingers_backlit_skin():
    """Three finger-like capped cylinders (1.4, 1.8 and 2.2 cm across, 8 cm long) side by side, lit
    from behind by a sun, a little fill in front; skin with a 1.2 cm red radius (Random Walk Skin)."""
    scene = kit.reset_scene(world_color=(0.015, 0.015, 0.02))
    skin = kit.skin(method="RANDOM_WALK_SKIN", scale=0.012)
    for i, (x, r) in enumerate(((-0.035, 0.007), (0.0, 0.009), (0.037, 0.011))):
        finger = kit.add_object(scene, f"Finger {i + 1}", kit.cylinder_mesh(f"Finger {i + 1}", r, 0.08, rings=10))
        finger.location = (x, 0.0, -0.04)
        finger.data.materials.append(skin)
        kit.add_subsurf(finger, 1)
    kit.add_camera(scene, (0.0, -0.3, 0.0), (0.0, 0.0, 0.0), lens=50.0)
    kit.add_light(scene, "Back", "SUN", (0.2, 1.0, 0.25), (0.0, 0.0, 0.0), 4.0, angle=math.radians(1.0))
    kit.add_light(scene, "Fill", "AREA", (-0.4, -0.5, 0.2), (0.0, 0.0, 0.0), 0.1, size=0.3)
    return scene


SCENES: dict[str, SuiteScene] = {
    f.__name__: SuiteScene(f.__name__, "backlit", f, (f.__doc__ or "").split("\n\n")[0].strip().replace("\n    ", " "))
    for f in (wedge_backlit_milk, torus_backlit_marble, fingers_backlit_skin)
}
