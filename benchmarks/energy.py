"""How much light Cycles' subsurface methods return compared with a Lambert surface of the same
Base Color: canonical renders, not scenes of the fidelity suite.

``python -m benchmarks.energy`` (about 15 minutes on a loaded 2-core machine) writes
``benchmarks/results/energy.json``; ``python -m benchmarks.energy --write-table`` copies its table
into ``core/optics/energy.py`` (``SEMI_INFINITE``), which reads nothing else.

The scene: four boxes 20 x 20 x 10 cm side by side, their top faces at z = 0, lit straight from
above by a sun (no world light, nothing else in the scene), seen by an orthographic camera tilted
by the view angle from the vertical. Every channel of a box has its own Base Color (12 albedos
over the four boxes) and the same mean free path, 0.5 mm as the method reads Radius x Scale
(``core.pipeline.mapping.mean_free_path``): even at albedo 0.95 the diffusion length (about 13 mm) is a
small fraction of the box, so the middle of each top face sees a semi-infinite medium under
uniform light. Per box and channel the figure is the light of the Diffuse passes (Diffuse Color
x (Direct + Indirect), where Cycles writes subsurface light) averaged over the middle half of the
top face (selected by the Position pass), with the method's subsurface against the same render
with Subsurface Weight 0: both share the specular layer above the diffuse one, so the ratio is
the subsurface method's reflectance over Lambert's.

Cycles 5.2 (``kernel/integrator/subsurface.h``, ``subsurface_random_walk.h``, docs/references.md
§14): the camera ray enters the random-walk media by refraction through the rough surface (the
material's IOR and Roughness; Random Walk (Skin): the Subsurface IOR, roughness 1, and half of
the entries cosine-distributed), walks with the single-scattering albedo inverted from Base
Color, and where it leaves, a Lambert BSDF of weight 1 gathers the light. The light's direction
therefore acts as it does on a Lambert surface; the view direction (through the refraction) and
the IOR may not, so the table is measured at several view angles and IORs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results", "energy.json")

#: The 12 albedos, as (box, channel): box i has channels ALBEDOS[i], ALBEDOS[i + 4], ALBEDOS[i + 8].
ALBEDOS = (0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95)
METHODS = ("RANDOM_WALK", "RANDOM_WALK_SKIN", "RANDOM_WALK_LEGACY", "BURLEY")
#: Mean free path as the method reads it (metres).
MFP = 0.0005
BOX = (0.2, 0.2, 0.1)
GAP = 0.06
#: The canonical material: the suite's typical IOR and roughness.
IOR = 1.45
ROUGHNESS = 0.35


def _box_colors() -> list[tuple[float, float, float]]:
    return [(ALBEDOS[i], ALBEDOS[i + 4], ALBEDOS[i + 8]) for i in range(4)]


def build(
    method: str,
    *,
    view_deg: float,
    ior: float,
    roughness: float,
    sun_deg: float,
    weight: float,
    mfp: float,
    depths=(BOX[2],) * 4,
    colors=None,
    light: str = "above",
):
    """The canonical scene: four boxes of ``depths`` (top faces at z = 0) with ``colors`` (default
    ``_box_colors()``), a sun ``sun_deg`` from the vertical (``light="above"``) or straight from
    below (``"below"``)."""
    import bpy
    from mathutils import Vector

    from benchmarks import scene_kit as kit
    from sss_lab.core.pipeline.mapping import skin_radius_factor

    scene = kit.reset_scene(world_color=(0.0, 0.0, 0.0))
    scale = mfp * (4.0 * math.pi if method in ("BURLEY", "RANDOM_WALK_LEGACY") else 1.0)
    width = 4 * BOX[0] + 3 * GAP
    for i, color in enumerate(colors or _box_colors()):
        radius = (1.0, 1.0, 1.0)
        if method == "RANDOM_WALK_SKIN":
            # The Skin method multiplies the radius by sqrt(3 (1 - alpha')) per channel: divided
            # out, so that every channel's mean free path is ``mfp``.
            radius = tuple(float(1.0 / v) for v in skin_radius_factor(color, ior))
        mat = kit.new_material(
            f"M{i}", color, radius=radius, scale=scale, method=method, ior=ior, roughness=roughness, weight=weight
        )
        x = -width / 2 + BOX[0] / 2 + i * (BOX[0] + GAP)
        size = (BOX[0], BOX[1], depths[i])
        kit.add_object(
            scene,
            f"Box{i}",
            kit.box_mesh(f"Box{i}", size),
            location=(x, 0.0, -depths[i] / 2),
            material=mat,
            smooth=False,
        )
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = width * 1.02
    cam.data.clip_start, cam.data.clip_end = 0.01, 10.0
    a = math.radians(view_deg)
    cam.location = (0.0, -2.0 * math.sin(a), 2.0 * math.cos(a))
    cam.rotation_euler = (Vector((0, 0, 0)) - Vector(cam.location)).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    s = math.radians(sun_deg)
    sun = (math.sin(s), 0.0, math.cos(s)) if light == "above" else (0.0, 0.0, -1.0)
    kit.add_light(scene, "Sun", "SUN", sun, (0.0, 0.0, 0.0), 3.0, angle=0.0)
    # At least 12 rows over the middle half of the top face, however steep the view.
    px = 192 * max(1, math.ceil(12.0 / (192 * BOX[1] / 2 * math.cos(a) / (width * 1.02))))
    scene.render.resolution_x = px
    scene.render.resolution_y = max(16, int(round(px * (BOX[1] * math.cos(a) + BOX[2] * math.sin(a)) / width)) + 8)
    layer = scene.view_layers[0]
    for flag in ("use_pass_diffuse_direct", "use_pass_diffuse_indirect", "use_pass_diffuse_color", "use_pass_position"):
        setattr(layer, flag, True)
    return scene


def render_arrays(scene, samples: int, seed: int) -> dict[str, np.ndarray]:
    import bpy

    from sss_lab.blender import compat
    from sss_lab.core.scene import exr

    scene.cycles.samples, scene.cycles.seed = samples, seed
    compat.set_multilayer_exr(scene.render.image_settings)
    with tempfile.TemporaryDirectory(prefix="sss_lab_energy_") as tmp:
        path = os.path.join(tmp, "r.exr")
        scene.render.filepath = path
        bpy.ops.render.render(write_still=True, scene=scene.name)
        passes = exr.read_passes(path)
        return {k: np.array(passes[k], dtype=np.float64) for k in passes.names}


def _box_means(p: dict[str, np.ndarray]) -> np.ndarray:
    """(4, 3): the Diffuse passes' light over the middle half of each box's top face."""
    light = p["Diffuse Color"][..., :3] * (p["Diffuse Direct"][..., :3] + p["Diffuse Indirect"][..., :3])
    pos = p["Position"][..., :3]
    width = 4 * BOX[0] + 3 * GAP
    out = np.zeros((4, 3))
    for i in range(4):
        x = -width / 2 + BOX[0] / 2 + i * (BOX[0] + GAP)
        sel = (np.abs(pos[..., 0] - x) < BOX[0] / 4) & (np.abs(pos[..., 1]) < BOX[1] / 4) & (np.abs(pos[..., 2]) < 1e-4)
        if sel.sum() < 8:
            raise RuntimeError(f"box {i}: only {int(sel.sum())} pixels of its top face's middle")
        out[i] = light[sel].mean(axis=0)
    return out


def measure(method, *, view_deg=0.0, ior=IOR, roughness=ROUGHNESS, sun_deg=0.0, mfp=MFP, samples=64, seed=0) -> dict:
    """Per albedo of ``ALBEDOS``: the method's light over Lambert's (same scene, SSS weight 0)."""
    start = time.perf_counter()
    kw = {"view_deg": view_deg, "ior": ior, "roughness": roughness, "sun_deg": sun_deg, "mfp": mfp}
    sss = _box_means(render_arrays(build(method, weight=1.0, **kw), samples, seed))
    lam = _box_means(render_arrays(build(method, weight=0.0, **kw), samples, seed))
    ratio = sss / lam
    by_albedo = {}
    for i in range(4):
        for c in range(3):
            by_albedo[ALBEDOS[i + 4 * c]] = float(ratio[i, c])
    return {
        "method": method,
        **kw,
        "samples": samples,
        "seed": seed,
        "albedo": list(ALBEDOS),
        "ratio": [round(by_albedo[a], 4) for a in ALBEDOS],
        "seconds": round(time.perf_counter() - start, 1),
    }


#: Slab thicknesses in mean free paths (``measure_slabs``) and the albedos of their channels
#: (two sets of three: six albedos).
SLAB_MFPS = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 128.0)
SLAB_COLORS = ((0.2, 0.5, 0.8), (0.35, 0.65, 0.92))
SLAB_MFP = 0.001


def measure_slabs(method="RANDOM_WALK", *, light="above", samples=64, seed=0, mfp=SLAB_MFP) -> dict:
    """Slabs (20 x 20 cm, ``SLAB_MFPS`` mean free paths thick) seen from above, lit by a sun
    straight from above (``light="above"``) or straight from below (``"below"``): the top face's
    light over a Lambert top face's under the sun from above, per albedo of ``SLAB_COLORS``.
    From above, light that reaches the bottom leaves there and the ratio falls below the thick
    slab's; from below, it is the light that comes through."""
    start = time.perf_counter()
    kw = {"view_deg": 0.0, "ior": IOR, "roughness": ROUGHNESS, "sun_deg": 0.0, "mfp": mfp}
    ratio = {}
    for colors in SLAB_COLORS:
        rows = []
        for k in range(0, len(SLAB_MFPS), 4):
            geo = {"depths": tuple(t * mfp for t in SLAB_MFPS[k : k + 4]), "colors": [colors] * 4}
            sss = _box_means(render_arrays(build(method, weight=1.0, light=light, **kw, **geo), samples, seed))
            lam = _box_means(render_arrays(build(method, weight=0.0, light="above", **kw, **geo), samples, seed))
            rows += list(sss / lam)
        for c, a in enumerate(colors):
            ratio[a] = [round(float(r[c]), 4) for r in rows]
    albedos = sorted(ratio)
    return {
        "method": method,
        "light": light,
        "mfp": mfp,
        "samples": samples,
        "seed": seed,
        "thickness_mfp": list(SLAB_MFPS),
        "albedo": albedos,
        "ratio": [ratio[a] for a in albedos],  # per albedo, per thickness
        "seconds": round(time.perf_counter() - start, 1),
    }


#: Sphere radii in mean free paths (``measure_spheres``); the largest stands for a flat surface.
SPHERE_RADII = (2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 256.0)
SPHERE_MFP = 0.001
SPHERE_PX = 64


def build_spheres(method: str, radius_mfp: float, *, weight: float, mfp: float = SPHERE_MFP, px: int = SPHERE_PX):
    """Four spheres of radius ``radius_mfp`` mean free paths in a row, each with three of the 12
    albedos (``_box_colors``), under a uniform white world (every point of a convex object gets
    the same irradiance, so that the ratio to Lambert is the share of the light the curved medium
    returns, whatever direction it leaves in), seen by an orthographic camera, ``px`` pixels
    across each sphere's slot."""
    import bpy
    from mathutils import Vector

    from benchmarks import scene_kit as kit
    from sss_lab.core.pipeline.mapping import skin_radius_factor

    scene = kit.reset_scene(world_color=(1.0, 1.0, 1.0))
    r = radius_mfp * mfp
    scale = mfp * (4.0 * math.pi if method in ("BURLEY", "RANDOM_WALK_LEGACY") else 1.0)
    for i, color in enumerate(_box_colors()):
        radius = (1.0, 1.0, 1.0)
        if method == "RANDOM_WALK_SKIN":
            radius = tuple(float(1.0 / v) for v in skin_radius_factor(color, IOR))
        mat = kit.new_material(
            f"M{i}", color, radius=radius, scale=scale, method=method, ior=IOR, roughness=ROUGHNESS, weight=weight
        )
        sphere = kit.uv_sphere_mesh(f"S{i}", r, segments=96, rings=48)
        kit.add_object(scene, f"S{i}", sphere, location=((i - 1.5) * 3 * r, 0.0, 0.0), material=mat)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 12 * r
    cam.data.clip_start, cam.data.clip_end = 0.1 * r, 100 * r
    cam.location = (0.0, -10 * r, 0.0)
    cam.rotation_euler = (Vector((0, 0, 0)) - Vector(cam.location)).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 4 * px, px
    layer = scene.view_layers[0]
    for flag in ("use_pass_diffuse_direct", "use_pass_diffuse_indirect", "use_pass_diffuse_color", "use_pass_position"):
        setattr(layer, flag, True)
    return scene


def measure_spheres(method="RANDOM_WALK", *, samples=128, seed=0, mfp=SPHERE_MFP) -> dict:
    """Per albedo of ``ALBEDOS`` and radius of ``SPHERE_RADII``: the light of the spheres'
    visible pixels (Diffuse Color x (Direct + Indirect)) with the method over the same with
    Subsurface Weight 0."""
    start = time.perf_counter()
    ratio: dict[float, list[float]] = {a: [] for a in ALBEDOS}
    for k in SPHERE_RADII:
        light = []
        for weight in (1.0, 0.0):
            p = render_arrays(build_spheres(method, k, weight=weight, mfp=mfp), samples, seed)
            light.append(p["Diffuse Color"][..., :3] * (p["Diffuse Direct"][..., :3] + p["Diffuse Indirect"][..., :3]))
            pos = p["Position"][..., :3]
        r = k * mfp
        on = np.linalg.norm(pos, axis=-1) > 0
        for i in range(4):
            sel = on & (np.abs(pos[..., 0] - (i - 1.5) * 3 * r) < 1.2 * r)
            if sel.sum() < 100:
                raise RuntimeError(f"sphere {i}: only {int(sel.sum())} pixels")
            q = light[0][sel].sum(axis=0) / light[1][sel].sum(axis=0)
            for c in range(3):
                ratio[ALBEDOS[i + 4 * c]].append(round(float(q[c]), 4))
    return {
        "method": method,
        "mfp": mfp,
        "samples": samples,
        "seed": seed,
        "radius_mfp": list(SPHERE_RADII),
        "albedo": list(ALBEDOS),
        "ratio": [ratio[a] for a in ALBEDOS],  # per albedo, per radius
        "seconds": round(time.perf_counter() - start, 1),
    }


#: View angles of the table (degrees from the normal).
VIEWS = (0.0, 20.0, 40.0, 55.0, 65.0, 75.0, 85.0)


def cases(quick: bool = False) -> list[dict]:
    """The table (``TABLE_METHODS`` at ``VIEWS``, the canonical IOR and roughness), then the checks
    of what it leaves out: IOR, roughness, the sun's angle, the seed, the mean free path."""
    out = [
        {"method": m, "view_deg": v} for m in ("RANDOM_WALK", "RANDOM_WALK_SKIN", "RANDOM_WALK_LEGACY") for v in VIEWS
    ]
    out += [{"method": "BURLEY", "view_deg": v} for v in (0.0, 70.0)]
    if quick:
        return out
    for method in ("RANDOM_WALK", "RANDOM_WALK_SKIN", "RANDOM_WALK_LEGACY"):
        for ior in (1.3, 1.6):
            out.append({"method": method, "ior": ior, "view_deg": 75.0})
    out.append({"method": "RANDOM_WALK", "roughness": 0.05})
    out.append({"method": "RANDOM_WALK", "roughness": 0.8})
    out.append({"method": "RANDOM_WALK", "sun_deg": 60.0})
    out.append({"method": "RANDOM_WALK", "seed": 1})
    out.append({"method": "RANDOM_WALK", "mfp": MFP / 2})
    return out


TABLE_METHODS = ("RANDOM_WALK", "RANDOM_WALK_SKIN", "RANDOM_WALK_LEGACY")
ENERGY_MODULE = os.path.join(ROOT, "core", "energy.py")


def table_block(data: dict) -> str:
    """The tables of ``core/optics/energy.py`` from the results ``data``: ``SEMI_INFINITE`` per method of
    ``TABLE_METHODS`` (the rows at the canonical IOR, roughness and mean free path, seed 0), then
    ``SLAB_ABOVE`` and ``SLAB_BELOW`` per method measured."""
    lines = ["SEMI_INFINITE: dict[str, tuple[tuple[float, ...], ...]] = {"]
    for method in TABLE_METHODS:
        lines.append(f'    "{method}": (')
        for view in VIEWS:
            row = next(
                r
                for r in data["rows"]
                if r["method"] == method
                and r["view_deg"] == view
                and r["ior"] == IOR
                and r["roughness"] == ROUGHNESS
                and r["sun_deg"] == 0.0
                and r["mfp"] == MFP
                and r["seed"] == 0
            )
            lines.append("        (" + ", ".join(f"{v:.3f}" for v in row["ratio"]) + f"),  # {view:g} deg")
        lines.append("    ),")
    lines.append("}")
    for light, name in (("above", "SLAB_ABOVE"), ("below", "SLAB_BELOW")):
        lines.append(f"{name}: dict[str, tuple[tuple[float, ...], ...]] = {{")
        for s in data["slabs"]:
            if s["light"] != light:
                continue
            assert tuple(s["thickness_mfp"]) == SLAB_MFPS
            lines.append(f'    "{s["method"]}": (')
            for a, row in zip(s["albedo"], s["ratio"], strict=True):
                lines.append("        (" + ", ".join(f"{v:.3f}" for v in row) + f"),  # albedo {a:g}")
            lines.append("    ),")
        lines.append("}")
    lines += convex_block(data)
    return "\n".join(lines)


def convex_block(data: dict) -> list[str]:
    """``CONVEX`` of ``core/optics/energy.py`` from the sphere measurements of ``data``: per method and
    albedo, for each radius of ``core.optics.energy.CONVEX_RADII``, the sphere's light over the largest
    sphere's (a flat surface), divided by what the slab tables give a slab as thick as the
    sphere's chord along the normal (2 R) under the same light on both faces (f_above + f_below):
    the light a convex surface returns beyond a slab's (``core.optics.energy.apply_energy``)."""
    from sss_lab.core.optics.energy import CONVEX_RADII, slab_factors

    lines = ["CONVEX: dict[str, tuple[tuple[float, ...], ...]] = {"]
    for s in data.get("spheres", []):
        radii = list(s["radius_mfp"])
        flat = radii.index(max(radii))
        lines.append(f'    "{s["method"]}": (')
        for a, row in zip(s["albedo"], s["ratio"], strict=True):
            values = []
            for k in CONVEX_RADII:
                f_above, f_below = slab_factors(s["method"], np.full((1, 3), a), np.full((1, 3), 2.0 * k))
                values.append(row[radii.index(k)] / row[flat] / float(f_above[0, 0] + f_below[0, 0]))
            lines.append("        (" + ", ".join(f"{v:.3f}" for v in values) + f"),  # albedo {a:g}")
        lines.append("    ),")
    lines.append("}")
    return lines


def write_table(results: str = RESULTS, module: str = ENERGY_MODULE) -> None:
    """Replace the table between ``# BEGIN TABLE`` and ``# END TABLE`` of ``module``."""
    from sss_lab.core.base.files import write_text

    with open(results, encoding="utf-8") as fh:
        data = json.load(fh)
    with open(module, encoding="utf-8") as fh:
        text = fh.read()
    head, rest = text.split("# BEGIN TABLE\n", 1)
    _, tail = rest.split("# END TABLE\n", 1)
    write_text(module, head + "# BEGIN TABLE\n" + table_block(data) + "\n# END TABLE\n" + tail)
    print(f"Saved: '{module}'")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=128)
    parser.add_argument("--quick", action="store_true", help="the table only, without the checks")
    parser.add_argument(
        "--only",
        choices=("table", "slabs", "spheres"),
        help="measure one part and keep the other from --out (default: both)",
    )
    parser.add_argument("--out", default=RESULTS)
    parser.add_argument(
        "--write-table",
        action="store_true",
        help="only copy the tables of --out into core/optics/energy.py (no rendering)",
    )
    args = parser.parse_args(argv)
    if args.write_table:
        write_table(args.out)
        return 0
    import bpy

    old = {}
    if args.only and os.path.isfile(args.out):
        with open(args.out, encoding="utf-8") as fh:
            old = json.load(fh)
    start = time.perf_counter()
    rows, slabs, spheres = old.get("rows", []), old.get("slabs", []), old.get("spheres", [])
    if args.only in (None, "table"):
        rows = []
        for case in cases(args.quick):
            rows.append(measure(samples=args.samples, **case))
            print(json.dumps(rows[-1]), flush=True)
    if args.only in (None, "slabs"):
        slabs = []
        for method in TABLE_METHODS + ("BURLEY",):
            for light in ("above", "below"):
                slabs.append(measure_slabs(method, light=light, samples=args.samples))
                print(json.dumps(slabs[-1]), flush=True)
    if args.only in (None, "spheres"):
        spheres = []
        for method in TABLE_METHODS + ("BURLEY",):
            spheres.append(measure_spheres(method, samples=args.samples))
            print(json.dumps(spheres[-1]), flush=True)
    data = {
        "command": "python -m benchmarks.energy" + (" --quick" if args.quick else "") + f" --samples {args.samples}",
        "generated_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "blender": bpy.app.version_string,
        "total_seconds": round(time.perf_counter() - start + old.get("total_seconds", 0.0), 1),
        "mfp_m": MFP,
        "box_m": list(BOX),
        "rows": rows,
        "slabs": slabs,
        "spheres": spheres,
    }
    from benchmarks._common import write_results

    write_results(args.out, data)
    return 0


if __name__ == "__main__":
    sys.exit(main())
