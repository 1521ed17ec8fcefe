"""Cycles' random walk across a shadow edge, against Christensen-Burley's profile at the d the
techniques give it: how the light spreads, measured on a canonical scene (no suite scene).

``python -m benchmarks.profile_edge`` (a few minutes on a loaded 2-core machine) writes
``benchmarks/results/profile_edge.json`` and prints a table.

The scene: a box 30 x 30 x 15 cm, its top face at z = 0, with three albedos in its three channels
and the same mean free path ``MFP`` in each (as the method reads Radius x Scale,
``core.pipeline.mapping.mean_free_path``); a sun straight down (angle 0: a sharp shadow); a plate 4 cm
above the face covering x < 0, which casts its shadow but is invisible to the camera; an
orthographic camera straight down over x in [-``HALF_WIDTH``, ``HALF_WIDTH``]. No world light; the
plate is seen by shadow rays only (no light bounces off it into its shadow). Per
channel, the light of the Diffuse passes (Diffuse Color x (Direct + Indirect), where Cycles writes
subsurface light) averaged over the rows, as a function of x (the Position pass): the edge's
profile m(x). The same scene with Subsurface Weight 0 (Lambert) shows the step the light makes.

A radial profile R on a semi-infinite medium under a step of light (E for x > 0, 0 below) gives
m(x) = c Q(x), with Q the cumulative distribution of R's 1-D marginal q(u) = int R(sqrt(u^2 + v^2))
dv and c the lit level. Burley's R(r) = (e^{-r/d} + e^{-r/3d}) / (8 pi d r) has q(u) = (K0(|u| / d)
+ K0(|u| / 3d)) / (4 pi d) (K0: the modified Bessel function, computed as int_0^inf e^{-z cosh t}
dt). Per channel the benchmark fits c and a scale k on the d the techniques use (``core.pipeline.mapping``:
the method's mean free path over its albedo scaling) by least squares over x, and reports:

- ``k``: the scale on d that best matches the random walk (1: the mapping is right);
- ``shadow_mm``: the light carried into the shadow, int_{x<0} m(x) / c dx, in mm, measured and for
  Burley at k = 1 and at the fitted k (for a profile of mean distance |u| under its marginal it is
  half that mean: how far the light reaches);
- ``residual``: the RMS of m / c - Q_{k d} at the fitted k, and its value at a few distances, so
  that a profile shape Burley's cannot take (more or less peaked at the same reach) shows.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results", "profile_edge.json")

#: Mean free path of every channel as the method reads it (metres).
MFP = 0.006
#: The albedos, three per render (one per channel).
ALBEDO_SETS = ((0.2, 0.44, 0.8), (0.1, 0.6, 0.95))
METHODS = ("RANDOM_WALK", "RANDOM_WALK_SKIN")
#: Half the width the camera sees across the edge (metres), and the image's size.
HALF_WIDTH = 0.06
RESOLUTION = (768, 48)
BOX = (0.3, 0.3, 0.15)
IOR = 1.4
ROUGHNESS = 0.45


def build(method: str, colors, *, weight: float):
    import bpy
    from mathutils import Vector

    from benchmarks import scene_kit as kit
    from sss_lab.core.pipeline.mapping import skin_radius_factor

    scene = kit.reset_scene(world_color=(0.0, 0.0, 0.0))
    radius = (1.0, 1.0, 1.0)
    if method == "RANDOM_WALK_SKIN":
        # The Skin method multiplies the radius by sqrt(3 (1 - alpha')) per channel: divided out,
        # so that every channel's mean free path is MFP.
        radius = tuple(float(1.0 / v) for v in skin_radius_factor(colors, IOR))
    mat = kit.new_material(
        "M", colors, radius=radius, scale=MFP, method=method, ior=IOR, roughness=ROUGHNESS, weight=weight
    )
    kit.add_object(scene, "Box", kit.box_mesh("Box", BOX), location=(0.0, 0.0, -BOX[2] / 2), material=mat, smooth=False)
    plate = kit.add_object(
        scene, "Plate", kit.box_mesh("Plate", (BOX[0], BOX[1] * 1.5, 0.002)), location=(-BOX[0] / 2, 0.0, 0.04)
    )
    # It only casts the shadow: no ray but the shadow rays sees it (lit from above and facing the
    # lit face below, it would bounce light into its own shadow).
    for ray in ("camera", "diffuse", "glossy", "transmission", "volume_scatter"):
        setattr(plate, f"visible_{ray}", False)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 2 * HALF_WIDTH
    cam.data.clip_start, cam.data.clip_end = 0.01, 10.0
    cam.location = (0.0, 0.0, 1.0)
    cam.rotation_euler = (Vector((0, 0, 0)) - Vector(cam.location)).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    kit.add_light(scene, "Sun", "SUN", (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 3.0, angle=0.0)
    scene.render.resolution_x, scene.render.resolution_y = RESOLUTION
    layer = scene.view_layers[0]
    for flag in ("use_pass_diffuse_direct", "use_pass_diffuse_indirect", "use_pass_diffuse_color", "use_pass_position"):
        setattr(layer, flag, True)
    return scene


def edge_profile(p: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(x (N,), m (N, 3)): the Diffuse passes' light per column, averaged over the rows, at each
    column's mean x."""
    light = p["Diffuse Color"][..., :3] * (p["Diffuse Direct"][..., :3] + p["Diffuse Indirect"][..., :3])
    x = p["Position"][..., 0]
    return x.mean(axis=0), light.mean(axis=0)


def _k0(z: np.ndarray) -> np.ndarray:
    """K0(z) for z > 0: int_0^inf e^{-z cosh t} dt (trapezoid over t up to 12, where e^{-z cosh t}
    is below e^{-z 8e4}; 3000 steps, in blocks of z)."""
    z = np.asarray(z, np.float64)
    t = np.linspace(0.0, 12.0, 3001)
    cosh = np.cosh(t)[None, :]
    out = np.empty(z.size)
    flat = z.ravel()
    for i in range(0, flat.size, 1000):
        f = np.exp(-flat[i : i + 1000, None] * cosh)
        out[i : i + 1000] = np.sum(f[:, 1:] + f[:, :-1], axis=1) * 0.5 * (t[1] - t[0])
    return out.reshape(z.shape)


#: Q for d = 1 on |u| in [0, _Z_MAX] (Q_d(x) = Q_1(x / d)), built on first use.
_Z_MAX = 400.0
_TABLE: list = []


def _unit_edge() -> tuple[np.ndarray, np.ndarray]:
    if not _TABLE:
        n = 40000
        edges = np.linspace(0.0, _Z_MAX, n + 1)
        mid = 0.5 * (edges[1:] + edges[:-1])  # midpoints: K0 has a log singularity at 0
        q = (_k0(mid) + _k0(mid / 3.0)) / (4.0 * math.pi)
        steps = q * np.diff(edges)
        # The first cell holds the singularity: int_0^h K0(s / a) ds = h (1 - ln(h / 2a) - gamma)
        # to O(h^3 ln h) for small h.
        h, gamma = float(edges[1]), 0.5772156649015329
        steps[0] = sum(h * (1.0 - math.log(h / (2.0 * a)) - gamma) for a in (1.0, 3.0)) / (4.0 * math.pi)
        _TABLE[:] = [edges, np.concatenate([[0.0], np.cumsum(steps)])]
    return _TABLE[0], _TABLE[1]


def burley_edge(x: np.ndarray, d: float) -> np.ndarray:
    """Q(x) for Burley's profile of ``d``: the light at x under a step of light on x > 0, over
    the lit level (1/2 at the edge)."""
    edges, cum = _unit_edge()
    z = np.abs(np.asarray(x, np.float64)) / d
    if float(z.max()) > _Z_MAX:
        raise ValueError(f"x / d up to {float(z.max()):.0f}: beyond the table's {_Z_MAX:g}")
    half = np.interp(z, edges, cum)
    return np.where(np.asarray(x) >= 0, 0.5 + half, 0.5 - half)


def fit_scale(x: np.ndarray, m: np.ndarray, d: float, ks=None) -> dict:
    """The k (on a log grid, then refined) and level c minimizing |m - c Q_{k d}|^2 over x."""
    ks = np.exp(np.linspace(math.log(0.25), math.log(4.0), 41)) if ks is None else ks

    def solve(k):
        q = burley_edge(x, k * d)
        c = float(np.dot(q, m) / np.dot(q, q))
        return float(np.sum((m - c * q) ** 2)), c, q

    errs = [solve(k)[0] for k in ks]
    i = int(np.argmin(errs))
    lo, hi = ks[max(i - 1, 0)], ks[min(i + 1, len(ks) - 1)]
    fine = np.exp(np.linspace(math.log(lo), math.log(hi), 21))
    k = float(min(fine, key=lambda v: solve(v)[0]))
    _, c, q = solve(k)
    return {"k": k, "c": c, "q": q}


def _shadow_mm(x: np.ndarray, y: np.ndarray) -> float:
    """int_{x<0} y dx in mm (trapezoid over the columns left of the edge)."""
    sel = x < 0
    xs, ys = x[sel], y[sel]
    order = np.argsort(xs)
    xs, ys = xs[order], ys[order]
    return float(np.sum(0.5 * (ys[1:] + ys[:-1]) * np.diff(xs)) * 1000.0)


def measure(method: str, colors, *, samples: int, seed: int) -> list[dict]:
    from benchmarks.energy import render_arrays
    from sss_lab.core.optics.profiles import d_from_mean_free_path
    from sss_lab.core.pipeline.mapping import MAPPINGS

    start = time.perf_counter()
    x, m = edge_profile(render_arrays(build(method, colors, weight=1.0), samples, seed))
    _, lam = edge_profile(render_arrays(build(method, colors, weight=0.0), samples, seed))
    mapping = MAPPINGS[method][0]
    rows = []
    for c, a in enumerate(colors):
        d = float(d_from_mean_free_path(MFP, a, mapping))
        fit = fit_scale(x, m[:, c], d)
        level = fit["c"]
        shape = m[:, c] / level
        q1 = burley_edge(x, d)
        # The Lambert step's 10-90 % width, in pixels: how sharp the imaged edge is.
        lam_level = max(float(np.median(lam[x > HALF_WIDTH / 2, c])), 1e-30)
        lam_n = lam[:, c] / lam_level
        width = float(np.sum((lam_n > 0.1) & (lam_n < 0.9)))
        probes = {}
        for r in (-4, -2, -1, -0.5, 0.5, 1, 2):
            j = int(np.argmin(np.abs(x - r * d)))
            probes[f"{r:g}d"] = {
                "measured": round(float(shape[j]), 4),
                "burley_k1": round(float(q1[j]), 4),
                "burley_fit": round(float(fit["q"][j]), 4),
            }
        rows.append(
            {
                "method": method,
                "albedo": a,
                "mapping": mapping,
                "d_mm": round(d * 1000, 3),
                "k": round(fit["k"], 3),
                "level_over_lambert": round(level / lam_level, 4),
                "shadow_mm": {
                    "measured": round(_shadow_mm(x, shape), 3),
                    "burley_k1": round(_shadow_mm(x, q1), 3),
                    "burley_fit": round(_shadow_mm(x, fit["q"]), 3),
                },
                "residual_rms": {
                    "k1": round(float(np.sqrt(np.mean((shape - q1) ** 2))), 4),
                    "fit": round(float(np.sqrt(np.mean((shape - fit["q"]) ** 2))), 4),
                },
                "at": probes,
                "lambert_edge_px": width,
                "pixel_mm": round(2 * HALF_WIDTH / RESOLUTION[0] * 1000, 4),
            }
        )
    for r in rows:
        r["seconds"] = round(time.perf_counter() - start, 1)
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--out", default=RESULTS)
    args = parser.parse_args(argv)
    import bpy  # noqa: F401  (the module's Blender)

    from sss_lab.core.base.files import write_text

    start = time.perf_counter()
    rows = []
    for method in args.methods.split(","):
        for colors in ALBEDO_SETS:
            rows += measure(method, colors, samples=args.samples, seed=args.seed)
            for r in rows[-3:]:
                print(
                    f"{r['method']:<17} A {r['albedo']:<4} d {r['d_mm']:.2f} mm: k {r['k']:.2f}; into the shadow"
                    f" {r['shadow_mm']['measured']:.2f} mm (Burley {r['shadow_mm']['burley_k1']:.2f} at k 1,"
                    f" {r['shadow_mm']['burley_fit']:.2f} at k); RMS {r['residual_rms']['k1']:.4f} at k 1,"
                    f" {r['residual_rms']['fit']:.4f} at k",
                    flush=True,
                )
    data = {
        "command": "python -m benchmarks.profile_edge " + " ".join(argv if argv is not None else sys.argv[1:]),
        "definition": __doc__,
        "mfp_m": MFP,
        "samples": args.samples,
        "seed": args.seed,
        "resolution": list(RESOLUTION),
        "half_width_m": HALF_WIDTH,
        "rows": rows,
        "total_seconds": round(time.perf_counter() - start, 1),
    }
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    write_text(args.out, json.dumps(data, indent=1) + "\n")
    print(f"Saved: {args.out!r}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
