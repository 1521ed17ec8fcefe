"""Build SSS Lab's sample scenes with bpy and save them as .blend files.

This script is the source of the sample scenes: the .blend files are generated from it
(``python sample_blends/build_scenes.py [NAME ...] --out DIR``, or through
``sss_lab.sample_blends`` from the project's commands). Every scene uses Principled BSDF
materials with Blender 5.2's Random Walk subsurface method and realistic scales (metres).
"""

from __future__ import annotations

import argparse
import math
import os
import sys


def _nodes(idblock):
    from sss_lab.addon import compat

    compat.ensure_node_tree(idblock)


def _reset():
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 32
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 0
    scene.cycles.use_denoising = False
    scene.render.resolution_x = 128
    scene.render.resolution_y = 128
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    world = bpy.data.worlds.new("World")
    _nodes(world)
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.02, 0.02, 0.025, 1.0)
    scene.world = world
    return scene


def _material(name, base_color, *, radius=(1.0, 0.2, 0.1), scale=0.005, weight=1.0, method="RANDOM_WALK"):
    import bpy

    mat = bpy.data.materials.new(name)
    _nodes(mat)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.subsurface_method = method
    bsdf.inputs["Base Color"].default_value = (*base_color, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.5
    bsdf.inputs["Subsurface Weight"].default_value = weight
    bsdf.inputs["Subsurface Radius"].default_value = radius
    bsdf.inputs["Subsurface Scale"].default_value = scale
    bsdf.inputs["Subsurface Anisotropy"].default_value = 0.0
    return mat


def _camera(scene, location, target, lens=50.0):
    import bpy
    from mathutils import Vector

    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.location = location
    cam.data.lens = lens
    direction = Vector(target) - Vector(location)
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    return cam


def _light(scene, name, kind, location, target, energy, color=(1.0, 1.0, 1.0), **kw):
    import bpy
    from mathutils import Vector

    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    data.color = color
    for key, value in kw.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
    return obj


def build_head_frontlit():
    """A head-sized shape (subdivided Suzanne, ~0.2 m) lit from the front-left by a sun, so
    that a sharp shadow edge crosses it: the case for diffusion (SSSS, Burley)."""
    import bpy

    scene = _reset()
    bpy.ops.mesh.primitive_monkey_add(size=0.2, location=(0.0, 0.0, 0.0))
    head = bpy.context.active_object
    head.name = "Head"
    mod = head.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = 2
    bpy.ops.object.shade_smooth()
    skin = _material("Skin", (0.8, 0.55, 0.45), radius=(1.0, 0.35, 0.2), scale=0.01)
    head.data.materials.append(skin)
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.0, 0.25, -0.0))
    wall = bpy.context.active_object
    wall.name = "Backdrop"
    wall.rotation_euler = (math.radians(90), 0.0, 0.0)
    plain = bpy.data.materials.new("Backdrop")
    _nodes(plain)
    plain.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    wall.data.materials.append(plain)
    _camera(scene, (0.0, -0.75, 0.02), (0.0, 0.0, 0.0), lens=60.0)
    _light(scene, "Key", "SUN", (-1.0, -1.0, 0.6), (0.0, 0.0, 0.0), 3.0, angle=math.radians(2.0))
    return scene


SCENES = {
    "head_frontlit": build_head_frontlit,
}

#: The scene `make demo` runs on.
DEFAULT_SCENE = "head_frontlit"


def build(name: str, path: str) -> str:
    """Build the sample scene ``name`` and save it to ``path`` (parent folders created)."""
    import bpy

    if name not in SCENES:
        raise ValueError(f"unknown sample scene {name!r}; expected one of: {', '.join(SCENES)}")
    SCENES[name]()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(path), compress=True)
    return path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "names", nargs="*", default=list(SCENES), help=f"scenes to build (default: all of {list(SCENES)})"
    )
    parser.add_argument("--out", default=os.path.dirname(os.path.abspath(__file__)), help="folder for the .blend files")
    args = parser.parse_args(argv)
    for name in args.names:
        print("Saved:", build(name, os.path.join(args.out, f"{name}.blend")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
