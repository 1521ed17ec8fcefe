"""The benchmarks' scene toolkit: what their scripted Blender scenes are built with.

The fidelity suite (``benchmarks/fidelity/scenes.py``), its extra back-lit scenes and the energy,
edge and slab benchmarks build their scenes from these: the sample scenes' helpers
(``sample_blends/build_scenes.py``, loaded once here: ``reset_scene``, ``new_material``,
``plain_material``, ``add_object``, the meshes ``new_mesh``, ``uv_sphere_mesh``, ``box_mesh``,
``plane_mesh``, ``cylinder_mesh``, ``head_mesh``, ``ear_mesh``, ``add_subsurf``, ``add_camera``,
``add_light``, ``scatters``, ``sss_objects``), the suite's materials (``skin``, ``marble``,
``wax``, ``jade``, ``milk``), its meshes (``torus``, ``icosphere``, ``bowl``) and its props
(``shadow_bar``, ``floor``, ``wall``). Conventions: those of ``sample_blends/build_scenes.py``
(metres, Principled BSDF materials with every subsurface input set). Blender's modules are
imported where a function needs them, so that importing this module needs no Blender.
"""

from __future__ import annotations

import importlib.util
import math
import os

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _load_builders():
    """The sample scenes' builder module (``sample_blends/build_scenes.py``)."""
    path = os.path.join(_ROOT, "sample_blends", "build_scenes.py")
    spec = importlib.util.spec_from_file_location("sss_lab_sample_scenes", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_builders = _load_builders()
reset_scene = _builders.reset_scene
new_material = _builders.new_material
plain_material = _builders.plain_material
add_object = _builders.add_object
new_mesh = _builders.new_mesh
uv_sphere_mesh = _builders.uv_sphere_mesh
box_mesh = _builders.box_mesh
plane_mesh = _builders.plane_mesh
cylinder_mesh = _builders.cylinder_mesh
head_mesh = _builders.head_mesh
ear_mesh = _builders.ear_mesh
add_subsurf = _builders.add_subsurf
add_camera = _builders.add_camera
add_light = _builders.add_light
scatters = _builders.scatters
sss_objects = _builders.sss_objects


# --- Materials: Base Color, Subsurface Radius (longest channel 1) and Scale (metres) ----------
# Skin and marble from Jensen et al. 2001 (core/study/presets.py); wax and jade the presets' artistic
# values; milk an artistic choice too (a warm white whose red scatters furthest). Scales differ
# per scene where a scene needs a longer path (the suite's table, ``benchmarks/fidelity/scenes.py``,
# gives the result).


def skin(name="Skin", method="RANDOM_WALK", scale=0.0037):
    return new_material(
        name, (0.436, 0.227, 0.131), radius=(1.0, 0.373, 0.185), scale=scale, method=method, ior=1.4, roughness=0.45
    )


def marble(name="Marble", scale=0.0085):
    return new_material(name, (0.83, 0.791, 0.753), radius=(1.0, 0.655, 0.464), scale=scale, ior=1.5, roughness=0.3)


def wax(name="Wax", method="RANDOM_WALK", scale=0.008):
    return new_material(
        name, (0.9, 0.8, 0.6), radius=(1.0, 0.75, 0.5), scale=scale, method=method, ior=1.45, roughness=0.35
    )


def jade(name="Jade", scale=0.004):
    return new_material(name, (0.35, 0.62, 0.42), radius=(0.5, 1.0, 0.625), scale=scale, ior=1.6, roughness=0.25)


def milk(name="Milk", method="RANDOM_WALK", scale=0.0048):
    return new_material(
        name, (0.91, 0.88, 0.76), radius=(1.0, 0.54, 0.33), scale=scale, method=method, ior=1.35, roughness=0.3
    )


# --- Geometry --------------------------------------------------------------------------------


def torus(name, major, minor, segments=48, rings=24):
    import bmesh
    from mathutils import Vector

    def build(bm):
        verts = []
        for i in range(segments):
            a = 2 * math.pi * i / segments
            row = []
            for j in range(rings):
                b = 2 * math.pi * j / rings
                r = major + minor * math.cos(b)
                row.append(bm.verts.new(Vector((r * math.cos(a), r * math.sin(a), minor * math.sin(b)))))
            verts.append(row)
        for i in range(segments):
            for j in range(rings):
                i2, j2 = (i + 1) % segments, (j + 1) % rings
                bm.faces.new((verts[i][j], verts[i2][j], verts[i2][j2], verts[i][j2]))
        bmesh.ops.recalc_face_normals(bm, faces=bm.faces[:])

    return new_mesh(name, build)


def icosphere(name, radius, subdivisions=1):
    import bmesh

    def build(bm):
        bmesh.ops.create_icosphere(bm, subdivisions=subdivisions, radius=radius)

    return new_mesh(name, build)


def bowl(name, radius, wall, segments=40, steps=10):
    """A hemispherical bowl, open at the top (rim at z = 0, bottom at z = -radius), walls ``wall``
    thick: one closed surface (outer and inner hemispheres joined by the rim), built vertex by
    vertex so that the mesh is the same on every run."""
    import bmesh
    from mathutils import Vector

    inner = radius - wall

    def build(bm):
        rings = {"outer": [], "inner": []}
        for j in range(segments):
            phi = 2 * math.pi * j / segments
            c, s = math.cos(phi), math.sin(phi)
            for key, r in (("outer", radius), ("inner", inner)):
                ring = []
                for i in range(steps):
                    t = 0.5 * math.pi * i / steps
                    ring.append(bm.verts.new(Vector((r * math.cos(t) * c, r * math.cos(t) * s, -r * math.sin(t)))))
                rings[key].append(ring)
        poles = {"outer": bm.verts.new(Vector((0, 0, -radius))), "inner": bm.verts.new(Vector((0, 0, -inner)))}
        for j in range(segments):
            k = (j + 1) % segments
            o, o2, n, n2 = rings["outer"][j], rings["outer"][k], rings["inner"][j], rings["inner"][k]
            bm.faces.new((n[0], n2[0], o2[0], o[0]))  # the rim, facing up
            for i in range(steps - 1):
                bm.faces.new((o[i], o2[i], o2[i + 1], o[i + 1]))  # outside, facing out and down
                bm.faces.new((n[i + 1], n2[i + 1], n2[i], n[i]))  # inside, facing the centre
            bm.faces.new((o[-1], o2[-1], poles["outer"]))
            bm.faces.new((poles["inner"], n2[-1], n[-1]))
        if bm.calc_volume(signed=True) < 0:  # normals pointing in: turn every face
            bmesh.ops.reverse_faces(bm, faces=bm.faces[:])

    return new_mesh(name, build)


def shadow_bar(scene, location, size=(0.5, 0.006, 0.006), rotation=(0.0, 0.0, 0.0)):
    bar = add_object(
        scene,
        "Shadow Bar",
        box_mesh("Shadow Bar", size),
        location=location,
        rotation=rotation,
        material=plain_material("Shadow Bar", (0.05, 0.05, 0.05)),
        smooth=False,
    )
    bar.visible_camera = False  # there for its shadow only
    return bar


def floor(scene, z=0.0, color=(0.3, 0.3, 0.3), size=1.5):
    return add_object(
        scene,
        "Floor",
        plane_mesh("Floor", size, size),
        location=(0, 0, z),
        material=plain_material("Floor", color),
        smooth=False,
    )


def wall(scene, y, color=(0.25, 0.25, 0.25), z=0.3):
    return add_object(
        scene,
        "Wall",
        plane_mesh("Wall", 1.5, 1.2),
        location=(0.0, y, z),
        rotation=(math.radians(90), 0.0, 0.0),
        material=plain_material("Wall", color),
        smooth=False,
    )
