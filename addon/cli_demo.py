"""``python -m sss_lab demo``: the main job on the bundled sample scene.

Builds the default sample scene from ``sample_blends/build_scenes.py``, renders the passes the
techniques need into a multilayer EXR with its scene description beside it, and writes a PNG
preview. Later steps of the pipeline extend it until it produces the comparison report.
"""

from __future__ import annotations

import importlib.util
import os
import time

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def add_parser(subparsers):
    p = subparsers.add_parser("demo", help="run the main job on the bundled sample scene (needs bpy)")
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--scene", default=None, help="sample scene name (default: the demo scene)")
    p.add_argument("--samples", type=int, default=32, help="Cycles samples for the passes (default 32)")
    p.set_defaults(run=run)


def load_sample_scenes():
    """The sample-scene builder module (a source checkout only: the extension zip leaves it out)."""
    from .cli import CommandError

    path = os.path.join(_ROOT, "sample_blends", "build_scenes.py")
    if not os.path.isfile(path):
        raise CommandError(f"the sample scenes are not here ({path} is missing); run from a source checkout")
    spec = importlib.util.spec_from_file_location("sss_lab_sample_scenes", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run(args) -> int:
    from .cli import CommandError, require_bpy

    bpy = require_bpy()
    if args.samples < 1:
        raise CommandError(f"--samples: expected an integer >= 1, got {args.samples}")
    scenes = load_sample_scenes()
    name = args.scene or scenes.DEFAULT_SCENE
    if name not in scenes.SCENES:
        raise CommandError(f"unknown sample scene {name!r}; expected one of: {', '.join(scenes.SCENES)}")
    out = os.path.abspath(os.path.join(args.out, name))
    os.makedirs(out, exist_ok=True)
    blend = scenes.build(name, os.path.join(out, f"{name}.blend"))
    print(f"Saved: {blend}")

    from ..operators.describe import describe_scene
    from . import compat

    scene = bpy.context.scene
    scene.cycles.samples = args.samples
    layer = scene.view_layers[0]
    for prop in (
        "use_pass_diffuse_direct",
        "use_pass_diffuse_indirect",
        "use_pass_diffuse_color",
        "use_pass_z",
        "use_pass_normal",
        "use_pass_position",
        "use_pass_material_index",
        "use_pass_object_index",
    ):
        setattr(layer, prop, True)
    start = time.perf_counter()
    bpy.ops.render.render(write_still=False)
    seconds = time.perf_counter() - start
    result = bpy.data.images["Render Result"]
    exr = os.path.join(out, "passes.exr")
    compat.set_multilayer_exr(scene.render.image_settings)
    result.save_render(filepath=exr, scene=scene)
    print(f"Saved: {exr}")
    with open(os.path.join(out, "passes.json"), "w", encoding="utf-8") as fh:
        fh.write(describe_scene(scene, meta={"samples": args.samples}).to_json())
    print(f"Saved: {os.path.join(out, 'passes.json')}")
    compat.set_single_image(scene.render.image_settings, "PNG", color_depth="8")
    png = os.path.join(out, "render.png")
    result.save_render(filepath=png, scene=scene)
    print(f"Saved: {png}")
    print(
        f"Rendered {name} at {scene.render.resolution_x}x{scene.render.resolution_y}, "
        f"{args.samples} samples, in {seconds:.1f} s"
    )
    return 0
