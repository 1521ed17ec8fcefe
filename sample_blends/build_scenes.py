"""Build SSS Lab's sample scenes with bpy and save them as .blend files.

This script is the source of the sample scenes: the .blend files are generated from it
(``python sample_blends/build_scenes.py [NAME ...] --out DIR``; the project's commands load
this file with ``blender.samples.load_sample_scenes`` and call ``build(name, path)``). Every scene uses Principled BSDF
materials with Blender 5.2's Random Walk subsurface method and realistic scales (metres); on
Blender 4.5 the legacy Random Walk, its only one, with the Subsurface Scale that gives the same
mean free path (see ``new_material``). Its helpers (``reset_scene``, ``new_material``,
``add_object``, the ``*_mesh`` builders, ``add_camera``, ``add_light`` ...) are public: the
benchmarks' scene toolkit (``benchmarks/scene_kit.py``) builds their scenes with them.

The scenes (``SCENES``), each meant for some of the techniques:

- ``head_frontlit``: a head-sized shape lit from the side by a small sun, with a sharp shadow
  edge across the face (diffusion: SSSS, Burley).
- ``backlit_thin``: an ear-like lobe and a thin curved leaf in front of a strong back light; the
  camera sees their unlit side (translucency: STA).
- ``wax_marble``: a wax candle and a marble ball with a long mean free path (up to 2 cm) and
  strongly different per-channel radii, a sharp shadow line across both (colour bleeding).
- ``depth_leak``: SSS and non-SSS objects at different depths overlapping on screen (light that
  screen-space techniques leak across depth discontinuities).
- ``asset_head``: the head built as assets are: a low-poly cage subdivided at render time only,
  its skin a node-group shader with an image-textured Base Color behind a glossy coat, and a
  marble ball textured by a noise (inputs read per pixel from the render).

Conventions shared by all scenes:

- Lengths in metres; objects 5-30 cm; Subsurface Radius x Subsurface Scale is the mean free
  path per channel: 3 mm to 2 cm for the longest channel (one to several pixels at 128x128),
  no channel under 1 mm.
- Every subsurface input of every material is set explicitly (Subsurface IOR too, although the
  Random Walk method reads the IOR input instead; a material without SSS has Weight 0), or
  linked (``asset_head``), a linked socket keeping Blender's default.
- SSS materials get pass indices 1, 2, ... in name order (the order in which
  ``blender.describe.sss_materials`` numbers them), other materials 0; mesh objects get
  object pass indices 1, 2, ... in name order.
- Cycles on the CPU, 32 samples, fixed seed, adaptive sampling and denoising off, 128x128 (scale
  ``render.resolution_percentage`` or the resolution up for larger pictures).
- The SSS meshes carry a baked thickness attribute "Thickness" (``blender/bake.py``,
  translucency convention, attribute target, few rays) wired into their materials as the Shader
  AOV "Thickness", and the view layer declares that AOV, so STA can run on the file as saved.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

#: Rays per vertex for the thickness bake of the sample scenes: enough for a smooth map on
#: these meshes (the bake's own noise is a binomial of this many rays, sigma <= 0.5/sqrt(64)).
THICKNESS_SAMPLES = 64
#: The thickness AOV the techniques read (core/pipeline/plan.py THICKNESS).
THICKNESS_AOV = "Thickness"


def _nodes(idblock):
    from sss_lab.blender import compat

    compat.ensure_node_tree(idblock)


def reset_scene(world_color=(0.02, 0.02, 0.025)):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 32
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 0
    scene.cycles.use_animated_seed = False
    scene.cycles.use_denoising = False
    scene.render.resolution_x = 128
    scene.render.resolution_y = 128
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.unit_settings.system = "METRIC"
    scene.unit_settings.scale_length = 1.0
    world = bpy.data.worlds.new("World")
    _nodes(world)
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*world_color, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world
    return scene


def _socket(node, identifier):
    """An input by identifier: Blender 5.2 hides unavailable inputs (Subsurface IOR outside the
    Skin method) from lookups by name."""
    return next(s for s in node.inputs if s.identifier == identifier)


def new_material(
    name,
    base_color,
    *,
    radius=(1.0, 0.2, 0.1),
    scale=0.005,
    weight=1.0,
    method=None,
    ior=1.4,
    anisotropy=0.0,
    roughness=0.5,
):
    """A Principled BSDF material with every subsurface input set. ``radius`` x ``scale`` is
    the mean free path per channel, in metres; ``weight`` 0 makes a material without SSS.

    ``method`` (a scene-description name) defaults to this Blender's newest random walk. On
    Blender 4.5 that is the legacy random walk, whose mean free path is radius x scale / (4 pi)
    (``core/pipeline/mapping.py``): the scale is multiplied by 4 pi there, so that the material keeps its
    mean free path on both versions."""
    import bpy

    from sss_lab.blender import compat

    mat = bpy.data.materials.new(name)
    _nodes(mat)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    if method is None:
        method = compat.random_walk_method()
        if method == "RANDOM_WALK_LEGACY":
            scale *= 4.0 * math.pi
    bsdf.subsurface_method = compat.subsurface_method_item(method)
    bsdf.inputs["Base Color"].default_value = (*base_color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["IOR"].default_value = ior  # Random Walk's boundary IOR
    compat.set_thin_wall(bsdf, False)
    bsdf.inputs["Subsurface Weight"].default_value = weight
    bsdf.inputs["Subsurface Radius"].default_value = radius
    bsdf.inputs["Subsurface Scale"].default_value = scale
    bsdf.inputs["Subsurface Anisotropy"].default_value = anisotropy
    _socket(bsdf, "Subsurface IOR").default_value = ior  # read by the Skin method only
    mat.diffuse_color = (*base_color, 1.0)  # viewport colour
    return mat


def plain_material(name, base_color, roughness=0.5):
    """A material without subsurface scattering (Subsurface Weight 0)."""
    return new_material(name, base_color, weight=0.0, roughness=roughness, ior=1.5)


def add_object(scene, name, mesh, location=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0), material=None, smooth=True):
    import bpy

    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = rotation
    if smooth:
        mesh.shade_smooth()
    if material is not None:
        mesh.materials.append(material)
    return obj


def new_mesh(name, build):
    """A mesh from a bmesh builder ``build(bm)``, its edges and faces in a canonical order
    (``_canonical``): the same mesh on every run."""
    import bmesh
    import bpy

    bm = bmesh.new()
    try:
        build(bm)
        canonical = _canonical(bm)
    finally:
        bm.free()
    mesh = bpy.data.meshes.new(name)
    canonical.to_mesh(mesh)
    canonical.free()
    return mesh


def _canonical(bm):
    """A new bmesh with ``bm``'s vertices (same order, same coordinates) and faces (each from the
    same corner), its edges as (lower, higher) vertex index sorted, its faces sorted by their
    vertex indices.

    Why: ``bmesh.ops.create_uvsphere`` lists the edges and faces of the same sphere in an order
    that follows the memory addresses of its elements, so that it changes from one run to the
    next (and within a run whenever other meshes are alive), and it turns some edges around. The
    vertices are the same, but what is built on the numbering is not: the Subdivision Surface
    modifier gave the ear of the fidelity suite's ``ear_backlit_skin`` its new vertices in
    another order on each run and some at positions a few units in the last place apart, hence
    another thickness bake (a new key for the cached passes), other passes (Combined up to 1e-6
    apart) and other errors (no SSS 1.3705710087, then 1.3705710096).

    Only the geometry is carried over: a builder that adds UVs, attributes or other layers is
    refused here rather than losing them silently."""
    import bmesh

    layers = [
        f"{domain} {kind} {name!r}"
        for domain, elements in (("vertex", bm.verts), ("edge", bm.edges), ("face", bm.faces), ("corner", bm.loops))
        for kind in dir(elements.layers)
        if isinstance(getattr(elements.layers, kind), bmesh.types.BMLayerCollection)
        for name in getattr(elements.layers, kind).keys()
    ]
    if layers:
        raise ValueError(f"the built mesh has layers that would be lost: {', '.join(layers)}; expected geometry only")
    bm.verts.index_update()
    faces = [(tuple(v.index for v in f.verts), f.smooth, f.material_index) for f in bm.faces]
    edges = {tuple(sorted(v.index for v in e.verts)) for e in bm.edges}
    out = bmesh.new()
    verts = [out.verts.new(v.co) for v in bm.verts]
    for a, b in sorted(edges):
        out.edges.new((verts[a], verts[b]))
    for corners, smooth, material in sorted(faces, key=lambda f: (sorted(f[0]), f[0])):
        face = out.faces.new([verts[i] for i in corners])
        face.smooth, face.material_index = smooth, material
    return out


def uv_sphere_mesh(name, radius, scale=(1.0, 1.0, 1.0), segments=32, rings=16):
    import bmesh

    def build(bm):
        bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)
        bmesh.ops.scale(bm, vec=scale, verts=bm.verts)

    return new_mesh(name, build)


def box_mesh(name, size, cuts=0):
    """A box centred on the origin; ``cuts`` cuts per edge give a baked attribute room to vary."""
    import bmesh

    def build(bm):
        bmesh.ops.create_cube(bm, size=1.0)
        bmesh.ops.scale(bm, vec=size, verts=bm.verts)
        if cuts:
            bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=cuts, use_grid_fill=True)

    return new_mesh(name, build)


def plane_mesh(name, size_x, size_y):
    import bmesh

    def build(bm):
        bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=0.5)
        bmesh.ops.scale(bm, vec=(size_x, size_y, 1.0), verts=bm.verts)

    return new_mesh(name, build)


def cylinder_mesh(name, radius, depth, segments=32, rings=8):
    """A capped cylinder standing on z = 0, cut into ``rings`` bands."""
    import bmesh

    def build(bm):
        bmesh.ops.create_cone(
            bm, cap_ends=True, cap_tris=False, segments=segments, radius1=radius, radius2=radius, depth=depth
        )
        bmesh.ops.translate(bm, vec=(0.0, 0.0, depth / 2), verts=bm.verts)
        side = [e for e in bm.edges if abs(e.verts[0].co.z - e.verts[1].co.z) > depth / 2]
        bmesh.ops.subdivide_edges(bm, edges=side, cuts=rings - 1, use_grid_fill=True)

    return new_mesh(name, build)


def add_subsurf(obj, levels=2):
    mod = obj.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = levels
    return mod


def add_camera(scene, location, target, lens=50.0):
    import bpy
    from mathutils import Vector

    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.location = location
    cam.data.lens = lens
    cam.data.sensor_fit = "AUTO"
    cam.data.clip_start = 0.01
    cam.data.clip_end = 20.0
    direction = Vector(target) - Vector(location)
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    return cam


def add_light(scene, name, kind, location, target, energy, color=(1.0, 1.0, 1.0), **kw):
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
    obj.visible_camera = False  # lights light the scene; they are not part of the picture
    return obj


def head_mesh(name, size=(0.16, 0.19, 0.22)):
    """A closed, manifold head-like shape facing -Y: an ellipsoid (``size`` = width, depth,
    height in metres) with a nose, brow ridge, eye sockets, cheeks and a chin, displaced along
    the radius by smooth bumps. One closed surface, so that random walks and the thickness bake
    see a proper volume (no overlapping parts)."""
    import bmesh
    from mathutils import Vector

    bumps = (  # (centre on the unit sphere, width, height as a fraction of the radius)
        ((0.0, -0.93, -0.1), (0.07, 0.1, 0.2), 0.45),  # nose
        ((0.0, -0.97, -0.32), (0.11, 0.12, 0.06), 0.12),  # nose tip and nostrils
        ((0.0, -0.8, 0.25), (0.45, 0.2, 0.07), 0.08),  # brow ridge
        ((0.33, -0.85, 0.08), (0.12, 0.2, 0.09), -0.14),  # eye sockets
        ((-0.33, -0.85, 0.08), (0.12, 0.2, 0.09), -0.14),
        ((0.45, -0.75, -0.2), (0.2, 0.2, 0.15), 0.05),  # cheeks
        ((-0.45, -0.75, -0.2), (0.2, 0.2, 0.15), 0.05),
        ((0.0, -0.75, -0.62), (0.22, 0.2, 0.12), 0.08),  # chin
        ((0.0, -0.9, -0.48), (0.2, 0.12, 0.04), -0.04),  # mouth line
    )

    def build(bm):
        bmesh.ops.create_uvsphere(bm, u_segments=48, v_segments=32, radius=1.0)
        for v in bm.verts:
            d = v.co.normalized()
            r = 1.0
            for centre, width, height in bumps:
                q = sum(((d[i] - centre[i]) / width[i]) ** 2 for i in range(3))
                r += height * math.exp(-0.5 * q)
            v.co = Vector(d * r)
        bmesh.ops.scale(bm, vec=(size[0] / 2, size[1] / 2, size[2] / 2), verts=bm.verts)

    return new_mesh(name, build)


def _backdrop(scene):
    """The head scenes' dark grey backdrop, 30 cm behind the head, catching its shadow."""
    wall = add_object(
        scene,
        "Backdrop",
        plane_mesh("Backdrop", 2.0, 2.0),
        location=(0.0, 0.3, 0.0),
        rotation=(math.radians(90), 0.0, 0.0),
        material=plain_material("Backdrop", (0.2, 0.2, 0.2)),
        smooth=False,
    )
    wall.visible_shadow = True
    return wall


def _front_lights(scene) -> None:
    """The head scenes' small key sun from the front-left (1 degree) and soft fill from the right."""
    add_light(scene, "Key", "SUN", (-1.0, -0.45, 0.3), (0.0, 0.0, 0.0), 3.0, angle=math.radians(1.0))
    add_light(scene, "Fill", "AREA", (0.6, -0.6, 0.1), (0.0, 0.0, 0.0), 0.3, size=0.4)


def build_head_frontlit():
    """A head-sized shape (~16 x 19 x 22 cm, skin, red mean free path 1.2 cm) lit from the
    front-left by a small sun (1 degree), so that the terminator and the nose's shadow draw sharp
    shadow edges across the face: the case for diffusion (SSSS, Burley)."""
    scene = reset_scene()
    skin = new_material("Skin", (0.8, 0.52, 0.42), radius=(1.0, 0.35, 0.2), scale=0.012, roughness=0.45)
    head = add_object(scene, "Head", head_mesh("Head"), material=skin)
    add_subsurf(head, 1)
    _backdrop(scene)
    add_camera(scene, (0.0, -0.62, 0.03), (0.0, 0.0, 0.0), lens=60.0)
    _front_lights(scene)
    return scene


def ear_mesh(name, size=(0.07, 0.018, 0.12), cup=0.012):
    """An ear-like lobe facing -Y: a flattened ellipsoid (``size`` = width, thickness, height),
    thick in the middle and thin towards the rim, bent into a shallow cup (``cup`` metres deep
    at the rim)."""
    import bmesh

    def build(bm):
        bmesh.ops.create_uvsphere(bm, u_segments=32, v_segments=24, radius=0.5)
        bmesh.ops.scale(bm, vec=size, verts=bm.verts)
        for v in bm.verts:
            u, w = v.co.x / (size[0] / 2), v.co.z / (size[2] / 2)
            v.co.y += cup * (u * u + 0.5 * w * w)

    return new_mesh(name, build)


def _leaf_sheet(name, length=0.13, width=0.065, curl=0.012, arch=0.01):
    """A leaf outline as a single sheet in the XZ plane (to be solidified): pointed at both ends,
    curled across (``curl``) and arched along (``arch``), both towards +Y."""
    import bmesh

    def build(bm):
        bmesh.ops.create_grid(bm, x_segments=10, y_segments=20, size=0.5)
        for v in bm.verts:
            u, t = v.co.x, v.co.y  # both in [-0.5, 0.5]
            half = 0.5 * width * math.sin(math.pi * (t + 0.5)) ** 0.8
            x, z = 2.0 * u * half, t * length
            y = curl * (2.0 * u) ** 2 + arch * (1.0 - (2.0 * t) ** 2)
            v.co = (x, y, z)

    return new_mesh(name, build)


def build_backlit_thin():
    """Back-lit thin features: an ear-like skin lobe (7 x 12 cm, 1.8 cm thick in the middle, thin
    at the rim, red mean free path 1.2 cm) and a leaf (6.5 x 13 cm, 2.5 mm thick, green mean
    free path 4 mm) in front of a strong sun from behind; the camera sees their unlit side, so
    what it sees is the light that went through: the case for translucency (STA)."""
    scene = reset_scene(world_color=(0.015, 0.015, 0.02))
    skin = new_material("Ear Skin", (0.8, 0.5, 0.4), radius=(1.0, 0.35, 0.2), scale=0.012, roughness=0.45)
    ear = add_object(
        scene,
        "Ear",
        ear_mesh("Ear"),
        location=(-0.055, 0.0, 0.0),
        rotation=(0.0, 0.0, math.radians(12)),
        material=skin,
    )
    add_subsurf(ear, 1)
    green = new_material("Leaf", (0.3, 0.55, 0.1), radius=(0.5, 1.0, 0.3), scale=0.004, roughness=0.4)
    leaf = add_object(
        scene,
        "Leaf",
        _leaf_sheet("Leaf"),
        location=(0.06, 0.01, 0.0),
        rotation=(0.0, math.radians(-20), math.radians(-10)),
        material=green,
    )
    solid = leaf.modifiers.new("Solidify", "SOLIDIFY")
    solid.thickness = 0.0025
    solid.offset = 0.0
    solid.use_even_offset = True
    add_subsurf(leaf, 1)
    add_camera(scene, (0.0, -0.36, 0.01), (0.0, 0.0, 0.0), lens=50.0)
    add_light(scene, "Back", "SUN", (0.3, 1.0, 0.35), (0.0, 0.0, 0.0), 4.0, angle=math.radians(1.0))
    add_light(scene, "Fill", "AREA", (-0.4, -0.5, 0.2), (0.0, 0.0, 0.0), 0.15, size=0.3)
    return scene


def build_wax_marble():
    """A wax candle (8 cm across, 14 cm tall; mean free path 15 mm red, 7 mm green, 3 mm blue)
    and a marble ball (8 cm; 8.5 / 5.6 / 4 mm) on a grey floor, lit by a small spot light from
    the front-left; a thin horizontal bar between the light and them (not seen by the camera)
    draws a sharp shadow line across both: long mean free path and strong colour bleeding
    (reddened light far into the shadow and the unlit side)."""
    scene = reset_scene()
    wax = new_material("Wax", (0.92, 0.62, 0.32), radius=(1.0, 0.45, 0.2), scale=0.015, ior=1.45, roughness=0.35)
    candle = add_object(scene, "Candle", cylinder_mesh("Candle", 0.04, 0.14, rings=10), location=(-0.045, 0.0, 0.0))
    candle.data.materials.append(wax)
    add_subsurf(candle, 1)
    marble = new_material(
        "Marble", (0.88, 0.86, 0.82), radius=(0.85, 0.56, 0.4), scale=0.01, ior=1.5, anisotropy=0.0, roughness=0.25
    )
    add_object(scene, "Ball", uv_sphere_mesh("Ball", 0.04), location=(0.075, 0.03, 0.04), material=marble)
    add_object(
        scene, "Floor", plane_mesh("Floor", 1.5, 1.5), material=plain_material("Floor", (0.3, 0.3, 0.3)), smooth=False
    )
    bar = add_object(
        scene,
        "Shadow Bar",
        box_mesh("Shadow Bar", (0.5, 0.006, 0.006)),
        location=(0.0, -0.16, 0.16),
        material=plain_material("Shadow Bar", (0.05, 0.05, 0.05)),
        smooth=False,
    )
    bar.visible_camera = False  # it is there for its shadow only
    add_camera(scene, (0.0, -0.5, 0.16), (0.015, 0.0, 0.055), lens=60.0)
    add_light(scene, "Key", "SPOT", (-0.3, -0.35, 0.3), (0.0, 0.0, 0.06), 8.0, shadow_soft_size=0.002, spot_size=1.2)
    add_light(scene, "Fill", "AREA", (0.5, -0.3, 0.3), (0.0, 0.0, 0.05), 0.5, size=0.5)
    return scene


def build_depth_leak():
    """SSS and non-SSS objects at different depths, overlapping on screen: a jade ball (8 cm) in
    front, a small wax block (5 cm) front-right, a plastic box (9 cm, no SSS) in the middle, a
    skin head-like shape (12 x 14 x 17 cm) behind them and a wall (no SSS) at the back, lit by
    a small key light that casts sharp shadows from the front objects onto the ones behind. The
    reference keeps each object's light to itself; screen-space techniques blur it across the
    depth edges (light leaking between objects)."""
    scene = reset_scene()
    jade = new_material("Jade", (0.35, 0.7, 0.45), radius=(0.4, 1.0, 0.6), scale=0.01, ior=1.6, roughness=0.2)
    add_object(scene, "Jade Ball", uv_sphere_mesh("Jade Ball", 0.04), location=(-0.045, -0.1, -0.02), material=jade)
    wax = new_material("Soap", (0.9, 0.75, 0.55), radius=(1.0, 0.6, 0.35), scale=0.008, ior=1.45, roughness=0.35)
    block = add_object(
        scene,
        "Soap Block",
        box_mesh("Soap Block", (0.05, 0.035, 0.05), cuts=4),
        location=(0.065, -0.17, -0.035),
        rotation=(0.0, 0.0, math.radians(-25)),
        material=wax,
    )
    bevel = block.modifiers.new("Bevel", "BEVEL")
    bevel.width, bevel.segments = 0.006, 3
    box = add_object(
        scene,
        "Plastic Box",
        box_mesh("Plastic Box", (0.09, 0.09, 0.09)),
        location=(0.035, 0.0, -0.015),
        rotation=(0.0, 0.0, math.radians(30)),
        material=plain_material("Plastic", (0.12, 0.2, 0.55), roughness=0.3),
        smooth=False,
    )
    box_bevel = box.modifiers.new("Bevel", "BEVEL")
    box_bevel.width, box_bevel.segments = 0.003, 2
    skin = new_material("Skin", (0.8, 0.52, 0.42), radius=(1.0, 0.35, 0.2), scale=0.012, roughness=0.45)
    head = add_object(
        scene, "Head", head_mesh("Head", (0.12, 0.14, 0.17)), location=(-0.005, 0.15, 0.025), material=skin
    )
    add_subsurf(head, 1)
    add_object(
        scene,
        "Floor",
        plane_mesh("Floor", 1.5, 1.5),
        location=(0.0, 0.0, -0.06),
        material=plain_material("Floor", (0.3, 0.3, 0.3)),
        smooth=False,
    )
    add_object(
        scene,
        "Wall",
        plane_mesh("Wall", 1.5, 1.0),
        location=(0.0, 0.4, 0.4),
        rotation=(math.radians(90), 0.0, 0.0),
        material=plain_material("Wall", (0.25, 0.25, 0.25)),
        smooth=False,
    )
    add_camera(scene, (0.0, -0.6, 0.07), (0.0, 0.0, 0.0), lens=70.0)
    add_light(scene, "Key", "AREA", (-0.35, -0.4, 0.35), (0.0, 0.0, 0.0), 5.0, size=0.03)
    add_light(scene, "Rim", "SUN", (0.5, 0.6, 0.5), (0.0, 0.0, 0.0), 1.0, angle=math.radians(2.0))
    return scene


def mottled_image(name, color, size=64, seed=7):
    """A packed image (8-bit, linear values) of ``color`` varied by +-30 % in smooth blotches, from
    a fixed seed: a stand-in for a painted albedo texture."""
    import bpy
    import numpy as np

    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:size, 0:size] / size
    shade = np.zeros((size, size))
    for _ in range(10):
        fx, fy, phase = rng.integers(1, 5), rng.integers(1, 5), rng.uniform(0, 2 * math.pi)
        shade += np.sin(2 * math.pi * (fx * xs + fy * ys) + phase)  # whole periods: it tiles
    rgb = np.asarray(color) * (1.0 + 0.3 * shade / np.abs(shade).max())[..., None]
    rgba = np.concatenate([np.clip(rgb, 0.0, 1.0), np.ones((size, size, 1))], axis=2).astype(np.float32)
    image = bpy.data.images.new(name, size, size, alpha=True)
    image.colorspace_settings.name = "Non-Color"  # the values are linear reflectances
    image.pixels.foreach_set(rgba.ravel())
    image.pack()
    return image


def skin_asset_material(name, base_color, *, radius, scale):
    """Skin made the way an asset library makes it: the Principled BSDF inside a node group
    ("<name> Shader", inputs Albedo, Radius, Scale), its Base Color from an image texture and its
    Radius from an RGB node outside the group, behind a Mix Shader with a thin glossy coat; the
    inner Principled BSDF keeps Blender's defaults where its inputs are linked."""
    import bpy

    from sss_lab.blender import compat

    group = bpy.data.node_groups.new(f"{name} Shader", "ShaderNodeTree")
    group.interface.new_socket("Albedo", in_out="INPUT", socket_type="NodeSocketColor")
    group.interface.new_socket("Radius", in_out="INPUT", socket_type="NodeSocketVector")
    group.interface.new_socket("Scale", in_out="INPUT", socket_type="NodeSocketFloat")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    inside, outside = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    bsdf = group.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.subsurface_method = compat.subsurface_method_item(compat.random_walk_method())
    if compat.random_walk_method() == "RANDOM_WALK_LEGACY":
        scale *= 4.0 * math.pi  # the mean free path of new_material's convention
    bsdf.inputs["Roughness"].default_value = 0.45
    bsdf.inputs["IOR"].default_value = 1.4
    bsdf.inputs["Subsurface Weight"].default_value = 1.0
    bsdf.inputs["Subsurface Anisotropy"].default_value = 0.0
    _socket(bsdf, "Subsurface IOR").default_value = 1.4
    for socket, target in (("Albedo", "Base Color"), ("Radius", "Subsurface Radius"), ("Scale", "Subsurface Scale")):
        group.links.new(inside.outputs[socket], bsdf.inputs[target])
    group.links.new(bsdf.outputs[0], outside.inputs["Shader"])

    mat = bpy.data.materials.new(name)
    _nodes(mat)
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.inputs["Scale"].default_value = scale
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = mottled_image(f"{name} Albedo", base_color)
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["Generated"], texture.inputs["Vector"])
    tree.links.new(texture.outputs["Color"], node.inputs["Albedo"])
    tint = tree.nodes.new("ShaderNodeRGB")
    tint.outputs[0].default_value = (*radius, 1.0)
    tree.links.new(tint.outputs[0], node.inputs["Radius"])
    mix, coat = tree.nodes.new("ShaderNodeMixShader"), tree.nodes.new("ShaderNodeBsdfGlossy")
    coat.inputs["Roughness"].default_value = 0.25
    mix.inputs["Fac"].default_value = 0.08
    tree.links.new(node.outputs["Shader"], mix.inputs[1])
    tree.links.new(coat.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    mat.diffuse_color = (*base_color, 1.0)
    return mat


def build_asset_head():
    """The head of ``head_frontlit`` built as an asset is: a low-poly cage subdivided at render
    time only (0 levels in the viewport, 2 in the render), its skin a node-group shader with an
    image-textured Base Color behind a glossy coat (``skin_asset_material``); beside it a marble
    ball whose Base Color comes from a noise texture through a colour ramp."""
    scene = reset_scene()
    skin = skin_asset_material("Skin", (0.8, 0.52, 0.42), radius=(1.0, 0.35, 0.2), scale=0.012)
    head = add_object(scene, "Head", head_mesh("Head"), material=skin)
    cage = add_subsurf(head, 2)
    cage.levels = 0  # the viewport shows the cage; Cycles renders the subdivided surface
    marble = new_material("Marble", (0.83, 0.79, 0.75), radius=(1.0, 0.66, 0.46), scale=0.0085, roughness=0.3)
    tree = marble.node_tree
    noise, ramp = tree.nodes.new("ShaderNodeTexNoise"), tree.nodes.new("ShaderNodeValToRGB")
    noise.inputs["Scale"].default_value = 40.0
    ramp.color_ramp.elements[0].color = (0.62, 0.58, 0.55, 1.0)
    ramp.color_ramp.elements[1].color = (0.9, 0.87, 0.84, 1.0)
    tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    tree.links.new(ramp.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)  # Blender's default
    ball = uv_sphere_mesh("Ball", 0.04, segments=32, rings=16)
    add_object(scene, "Ball", ball, location=(-0.12, -0.06, -0.07), material=marble)
    _backdrop(scene)
    add_camera(scene, (-0.04, -0.62, 0.02), (-0.04, 0.0, -0.02), lens=50.0)
    _front_lights(scene)
    return scene


SCENES = {
    "head_frontlit": build_head_frontlit,
    "backlit_thin": build_backlit_thin,
    "wax_marble": build_wax_marble,
    "depth_leak": build_depth_leak,
    "asset_head": build_asset_head,
}

#: The scene `make demo` runs on.
DEFAULT_SCENE = "head_frontlit"


def sss_objects(scene) -> list:
    """Mesh objects of ``scene`` with at least one material that scatters (Subsurface Weight
    > 0), in name order."""
    result = []
    for obj in sorted(scene.objects, key=lambda o: o.name):
        if obj.type == "MESH" and any(scatters(slot.material) for slot in obj.material_slots):
            result.append(obj)
    return result


def scatters(mat) -> bool:
    """True when SSS Lab's scene reader finds subsurface scattering in ``mat`` (its Principled
    BSDF wherever Cycles finds it: in node groups, behind Mix Shaders)."""
    from sss_lab.blender.describe import material_sss

    info = material_sss(mat, 1) if mat is not None else None
    return info is not None and info.scatters


def _finish(scene) -> None:
    """Pass indices, the thickness AOV and the baked thickness of the SSS meshes."""
    from sss_lab.blender.bake import bake_thickness
    from sss_lab.core.scene.thickness import BakeSettings

    materials = {slot.material.name: slot.material for o in scene.objects for slot in o.material_slots if slot.material}
    index = 0
    for name in sorted(materials):
        mat = materials[name]
        if scatters(mat):
            index += 1
            mat.pass_index = index
        else:
            mat.pass_index = 0
    meshes = sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name)
    for i, obj in enumerate(meshes, start=1):
        obj.pass_index = i
    layer = scene.view_layers[0]
    if THICKNESS_AOV not in layer.aovs:
        aov = layer.aovs.add()
        aov.name, aov.type = THICKNESS_AOV, "VALUE"
    targets = sss_objects(scene)
    settings = BakeSettings(target="attribute", samples=THICKNESS_SAMPLES, attribute_name=THICKNESS_AOV)
    results = bake_thickness(scene, targets, settings, log=None)
    failed = [str(r) for r in results if r.status != "baked" or r.warnings]
    if failed:
        raise RuntimeError("thickness bake of the sample scene failed: " + "; ".join(failed))


def build(name: str, path: str) -> str:
    """Build the sample scene ``name`` and save it to ``path`` (parent folders created)."""
    import bpy

    if name not in SCENES:
        raise ValueError(f"unknown sample scene {name!r}; expected one of: {', '.join(SCENES)}")
    scene = SCENES[name]()
    _finish(scene)
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
        print(f"Saved: '{os.path.abspath(build(name, os.path.join(args.out, f'{name}.blend')))}'")
    return 0


if __name__ == "__main__":
    sys.exit(main())
