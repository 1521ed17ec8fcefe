"""Render the passes the techniques need: one multilayer EXR per frame plus its scene description.

``render_passes(scene, out_dir, techniques=...)`` is the plain function (scripts and the command
line call it); the operator ``bpy.ops.sss_lab.render_passes`` (``operators/render.py``) wraps it
for the panel.

What it does, per call, through ``SceneState`` (everything is put back afterwards, also when a
render or a save fails):

- Cycles, the given samples, adaptive sampling off (a fixed sample count, docs/references.md §8),
  the given seed, no denoising (Combined must hold the same noise as the diffuse passes the
  techniques subtract from it), no time limit, optionally a WxH resolution at 100 %.
- Only the chosen view layer renders, with exactly the passes of
  ``core.pipeline.plan.required_passes`` for the techniques switched on and every other pass, shader
  AOV and light group switched off (so a file holds what the techniques read, nothing else).
- Every Principled BSDF of the scene's materials renders as plain diffuse: Subsurface Weight 0
  (its links cut), the way a real-time engine sees the material (docs/references.md §7: the
  subsurface light would otherwise be inside the Diffuse passes).
- Material Pass Index = the index ``blender.describe.sss_materials`` gives each subsurface material
  (1, 2, ... in name order), 0 for every other material, so the Material Index pass matches
  the scene description written beside the EXR. For Burley, mesh objects whose Pass Index is 0
  get a free one, so that every object has its own Object Index.
- STA reads the thickness AOV (``SceneDescription.thickness_aov``, the panel's bake AOV name,
  "Thickness" by default) that ``blender/bake.py`` wires into the materials. When STA is asked
  for and no subsurface material has it, ``render_passes`` raises ValueError before rendering
  anything: bake thickness first, or leave STA out. (It does not skip STA silently: a
  render-farm job asked for STA passes should fail loudly rather than deliver files STA cannot
  use.) Subsurface materials without it are listed in the log; their thickness reads 0.

Each frame's file is written under a temporary name and renamed when complete, read back with
``core.scene.exr.read_passes`` and checked (every needed pass present, nothing else, Material Index
values known to the scene description).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import bpy
import numpy as np

from ..core.base import files, memory
from ..core.base.errors import DamagedFileError, OutputError, describe_os_error
from ..core.base.progress import printable, saved_line
from ..core.pipeline.plan import required_passes
from ..core.pipeline.sequence import frame_path, sidecar_path
from ..core.scene.passes import INPUT_AOVS, PASSES, InputAOV
from ..core.scene.scene import parse_resolution
from ..core.scene.thickness import CONVENTIONS
from ..core.techniques.registry import TECHNIQUES, check_technique
from . import compat
from .describe import describe_scene, input_sockets, sss_materials, walk_trees
from .jobs import Job, Progress, run
from .state import SceneState
from .thickness import thickness_aov_name, thickness_setup

#: File name of the passes of one frame; ``####`` is the frame number.
FILE_PATTERN = "passes_####.exr"

# Flags that are options of a pass rather than passes: left as they are.
_NOT_PASSES = frozenset({"use_pass_cryptomatte_accurate"})
# Cycles' own view-layer flags that add passes besides the ``use_pass_*`` ones.
_CYCLES_EXTRA_PASSES = ("denoising_store_passes", "pass_debug_sample_count", "pass_render_time")

_PRINCIPLED = "ShaderNodeBsdfPrincipled"


class NoSubsurfaceError(ValueError):
    """The scene has no material with subsurface scattering: there is nothing to render."""


def _check_techniques(techniques) -> list[str]:
    if isinstance(techniques, str):
        techniques = [techniques]
    out = []
    for t in techniques:
        if check_technique(t) not in out:
            out.append(t)
    if not out:
        raise ValueError(f"techniques: expected at least one of {', '.join(TECHNIQUES)}")
    return out


def needed_passes(techniques: Iterable[str], thickness_aov: str = "Thickness") -> list[str]:
    """The union of the passes ``techniques`` read, in a stable order."""
    names: list[str] = []
    for t in techniques:
        for name in required_passes(t, thickness_aov):
            if name not in names:
                names.append(name)
    return names


def _rendered_materials(scene) -> list:
    """The materials of every object the scene renders (meshes, curves, text...), each once."""
    found = {}
    for obj in scene.objects:
        if obj.hide_render:
            continue
        for slot in getattr(obj, "material_slots", ()):
            if slot.material is not None:
                found[slot.material.name_full] = slot.material
    return [found[k] for k in sorted(found)]


def zero_subsurface(st: SceneState, scene) -> list[str]:
    """Render every Principled BSDF of the scene's materials with Subsurface Weight 0, and every
    Subsurface Scattering node with Scale 0 (links cut): both as plain diffuse (Cycles renders a
    subsurface closure of no radius as a diffuse one, with its colour); ``st`` puts them back.
    Returns the materials changed."""
    seen: set = set()
    changed = []
    for mat in _rendered_materials(scene):
        if not mat.is_editable:
            if any(
                _socket_to_zero(node) is not None and _scatters(_socket_to_zero(node))
                for tree in walk_trees(mat.node_tree, set())
                for node in tree.nodes
            ):
                raise ValueError(
                    f"material {mat.name!r} is linked from a library, so its subsurface scattering cannot be switched"
                    " off for the passes; make it local (Object > Relations > Make Local)"
                )
            continue
        for tree in walk_trees(mat.node_tree, seen):
            for node in tree.nodes:
                socket = _socket_to_zero(node)
                if socket is None:
                    continue
                for link in list(socket.links):
                    from_socket, to_socket = link.from_socket, link.to_socket

                    def relink(tree=tree, a=from_socket, b=to_socket):
                        tree.links.new(a, b)

                    tree.links.remove(link)
                    st.on_restore(relink)
                    changed.append(mat.name)
                if socket.default_value != 0.0:
                    st.set(socket, "default_value", 0.0)
                    changed.append(mat.name)
    return sorted(set(changed))


def input_aovs_of(materials) -> list[InputAOV]:
    """The input AOVs some of ``materials`` (``MaterialSSS``) read per pixel, in the table's order."""
    keys = {k for m in materials for k in m.per_pixel}
    return [a for k, a in INPUT_AOVS.items() if k in keys]


def wire_input_aovs(st: SceneState, materials) -> None:
    """For each input a material reads per pixel (``MaterialSSS.per_pixel``), an AOV Output node
    beside its Principled BSDF (or Subsurface Scattering node), inside the node group that holds
    it, fed by the link that feeds the input: Cycles writes the input's value per pixel into the
    input's AOV. ``st`` removes the nodes."""
    done: set = set()
    for m in materials:
        if not m.per_pixel:
            continue
        material = bpy.data.materials.get(m.name)
        if material is None:
            continue
        for key, socket in input_sockets(material, m.per_pixel):
            link = next((lk for lk in socket.links if lk.is_valid and not getattr(lk, "is_muted", False)), None)
            if link is None:
                continue
            tree = socket.node.id_data
            ident = (tree.as_pointer(), key, link.from_node.name, link.from_socket.identifier)
            if ident in done:
                continue  # a node group two materials share: one AOV Output writes for both
            done.add(ident)
            aov = INPUT_AOVS[key]
            node = tree.nodes.new("ShaderNodeOutputAOV")
            node.aov_name = aov.name
            node.location = (socket.node.location.x, socket.node.location.y - 400)
            tree.links.new(link.from_socket, node.inputs[aov.socket])
            name = node.name

            def remove(tree=tree, name=name):
                added = tree.nodes.get(name)
                if added is not None:
                    tree.nodes.remove(added)

            st.on_restore(remove)


def _socket_to_zero(node):
    """The input that switches ``node``'s subsurface scattering off: a Principled BSDF's
    Subsurface Weight, a (not muted) Subsurface Scattering node's Scale; None for other nodes."""
    if node.bl_idname == _PRINCIPLED:
        return node.inputs.get("Subsurface Weight")
    if node.bl_idname == "ShaderNodeSubsurfaceScattering" and not node.mute:
        return node.inputs.get("Scale")
    return None


def _scatters(socket) -> bool:
    return socket.is_linked or socket.default_value > 0


def _material_indices(st: SceneState, scene, materials: list) -> None:
    """Pass Index = the scene description's index for subsurface materials, 0 for the others."""
    wanted = {m.name: m.index for m in materials}
    errors = []
    for mat in bpy.data.materials:
        target = wanted.get(mat.name, 0)
        if mat.pass_index == target:
            continue
        if not mat.is_editable:
            if mat.name in wanted:
                errors.append(
                    f"subsurface material {mat.name!r} is linked from a library and its Pass Index cannot be set"
                )
            elif mat.pass_index in wanted.values():
                errors.append(
                    f"material {mat.name!r} is linked from a library and has Pass Index {mat.pass_index}, "
                    "which SSS Lab needs for a subsurface material"
                )
            continue
        st.set(mat, "pass_index", target)
    if errors:
        raise ValueError("cannot set the material pass indices: " + "; ".join(errors) + " (make the material local)")


def _object_indices(st: SceneState, scene) -> dict[str, int]:
    """Give every rendered mesh object with Pass Index 0 a free index (Burley's Object Index)."""
    objects = [o for o in scene.objects if o.type == "MESH" and not o.hide_render]
    used = {o.pass_index for o in objects}
    nxt = max(used | {0}) + 1
    assigned = {}
    for obj in sorted(objects, key=lambda o: o.name):
        if obj.pass_index == 0 and obj.is_editable:
            st.set(obj, "pass_index", nxt)
            assigned[obj.name] = nxt
            nxt += 1
    return assigned


def _set_passes(st: SceneState, scene, layer, names: list[str], wanted_aovs: list[tuple[str, str]]) -> None:
    """Exactly ``names`` on ``layer``: every other pass flag, AOV and light group off;
    ``wanted_aovs`` the shader AOVs (name, type) the passes hold."""
    # The view-layer flags of the pass table (core/scene/passes.py); AOVs are set below.
    flags: set[str] = set()
    for n in names:
        flag = PASSES[n].flag if n in PASSES else None
        if flag:
            flags.add(flag)
    for owner in (layer, getattr(layer, "cycles", None)):
        if owner is None:
            continue
        for prop in owner.bl_rna.properties:
            ident = prop.identifier
            if prop.type != "BOOLEAN" or prop.is_readonly or ident in _NOT_PASSES:
                continue
            if not (ident.startswith("use_pass_") or ident in _CYCLES_EXTRA_PASSES):
                continue
            want = ident in flags
            if getattr(owner, ident) != want:
                st.set(owner, ident, want)
    missing_flags = flags - {p.identifier for p in layer.bl_rna.properties}
    if missing_flags:  # a Blender without one of them: say so rather than render without it
        raise RuntimeError(f"view layer has no pass flag(s) {', '.join(sorted(missing_flags))}")

    # Shader AOVs: exactly the wanted ones (the thickness AOV, the per-pixel inputs), the others
    # put back after.
    aovs = [(a.name, a.type) for a in layer.aovs]
    active = layer.active_aov_index if hasattr(layer, "active_aov_index") else None
    if aovs != wanted_aovs:

        def restore_aovs():
            while len(layer.aovs):
                layer.aovs.remove(layer.aovs[0])
            for name, kind in aovs:
                a = layer.aovs.add()
                a.name, a.type = name, kind
            if active is not None and aovs:
                layer.active_aov_index = min(active, len(aovs) - 1)

        st.on_restore(restore_aovs)
        while len(layer.aovs):
            layer.aovs.remove(layer.aovs[0])
        for name, kind in wanted_aovs:
            a = layer.aovs.add()
            a.name, a.type = name, kind

    groups = [g.name for g in getattr(layer, "lightgroups", ())]
    if groups:

        def restore_groups():
            for name in groups:
                if layer.lightgroups.get(name) is None:
                    layer.lightgroups.add(name=name)

        st.on_restore(restore_groups)
        while len(layer.lightgroups):
            layer.lightgroups.remove(layer.lightgroups[0])


def _pick_layer(scene, view_layer):
    if view_layer is None:
        ctx = bpy.context
        if ctx.scene == scene and ctx.view_layer is not None:
            return ctx.view_layer
        return scene.view_layers[0]
    if isinstance(view_layer, str):
        layer = scene.view_layers.get(view_layer)
        if layer is None:
            have = ", ".join(v.name for v in scene.view_layers)
            raise ValueError(f"view layer {view_layer!r} is not in scene {scene.name!r}; it has: {have}")
        return layer
    return view_layer


def _render(scene) -> None:
    """One still render of ``scene`` into the Render Result (a seam the tests wrap), refused first
    when its passes cannot fit in memory (``core.base.memory``)."""
    r = scene.render
    memory.check_frame(
        r.resolution_x * r.resolution_percentage // 100,
        r.resolution_y * r.resolution_percentage // 100,
        sum(_channels(layer) for layer in scene.view_layers if layer.use),  # the layers this render renders
        "the passes",
    )
    bpy.ops.render.render(write_still=False, scene=scene.name)


def _channels(layer) -> int:
    """Float values per pixel the view layer's passes hold: four for Combined, three per colour or
    vector pass, one per value pass and AOV (an estimate: what a pass switched on costs)."""
    count = 4
    for name in dir(layer):
        if name.startswith("use_pass_") and getattr(layer, name, False) is True:
            count += 3
    count += sum(1 if aov.type == "VALUE" else 4 for aov in layer.aovs)
    return count


def verify_passes(path: str, names: list[str], view_layer: str, indices: Iterable[int]) -> None:
    """Read ``path`` back: exactly the passes ``names``, and only known Material Index values."""
    from ..core.scene.exr import read_passes

    p = read_passes(path, view_layer)
    missing = [n for n in names if n not in p]
    extra = [n for n in p.names if n not in names]
    if missing or extra:
        raise RuntimeError(
            f"{path}: the render wrote the passes {', '.join(p.names)}; expected {', '.join(names)}"
            + (f" (missing {', '.join(missing)})" if missing else "")
            + (f" (unexpected {', '.join(extra)})" if extra else "")
        )
    mi = p["Material Index"]
    seen = {int(v) for v in np.unique(mi[np.isfinite(mi)])}
    unknown = seen - set(indices) - {0}
    if unknown:
        raise RuntimeError(f"{path}: Material Index values {sorted(unknown)} are not in the scene description")


def render_passes(scene, out_dir: str, *, progress: Callable[[int, int], None] | None = None, **options) -> list[str]:
    """Render the passes for each frame into ``out_dir``; returns the paths written.

    ``options``: those of ``render_passes_job``, which this runs to its end. ``progress(done,
    total)`` is called after each frame.
    """
    total: list[int] = []

    def step(p: Progress) -> None:
        total[:] = [p.total]
        if progress is not None and p.done:
            progress(p.done, p.total)

    written = run(render_passes_job(scene, out_dir, **options), step)
    if progress is not None and total:  # the last frame ends the job rather than yielding
        progress(total[0], total[0])
    return written


@dataclass(frozen=True)
class _Plan:
    """What ``render_passes_job`` renders, checked before anything changes."""

    techniques: list
    layer: Any
    materials: list
    aov_name: str
    needs_thickness: bool
    convention: str
    names: list
    out_dir: str
    #: (frame, EXR path) per frame.
    targets: list
    #: The shader AOVs of the inputs read per pixel (``core.scene.passes.INPUT_AOVS``), [] when
    #: every input is a constant.
    input_aovs: list


def _check_numbers(samples, seed) -> None:
    if samples is not None and (not isinstance(samples, int) or isinstance(samples, bool) or samples < 1):
        raise ValueError(f"samples: expected an integer >= 1, got {samples!r}")
    if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool) or seed < 0):
        raise ValueError(f"seed: expected an integer >= 0, got {seed!r}")


def _targets(out_dir: str, frames: list[int], overwrite: bool) -> tuple[str, list]:
    """(the absolute output folder, (frame, EXR path) per frame); FileExistsError for a file
    in the way (any existing one unless ``overwrite``)."""
    out_dir = os.path.abspath(os.fspath(out_dir))
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise ValueError(f"output folder {out_dir!r} exists and is not a folder")
    targets = [(f, os.path.join(out_dir, frame_path(FILE_PATTERN, f))) for f in frames]
    if not overwrite:
        existing = [p for _, exr in targets for p in (exr, sidecar_path(exr)) if os.path.exists(p)]
        if existing:
            raise FileExistsError(
                f"{existing[0]} already exists; refusing to overwrite it (choose another folder or overwrite; "
                "on the command line --overwrite, or --skip-existing to keep the finished frames)"
            )
    not_files = [
        p for _, exr in targets for p in (exr, sidecar_path(exr)) if os.path.lexists(p) and not os.path.isfile(p)
    ]
    if not_files:
        raise FileExistsError(f"{not_files[0]} is a folder or not a regular file; refusing to write over it")
    return out_dir, targets


def _plan(scene, out_dir, *, techniques, frames, view_layer, overwrite, say) -> _Plan:
    """Check the scene and the output for ``render_passes_job``; raises before anything changes."""
    frames = [scene.frame_current] if frames is None else [int(f) for f in frames]
    if not frames:
        raise ValueError("frames: expected at least one frame")
    if scene.camera is None:
        raise ValueError(f"scene {scene.name!r} has no active camera; set one in Scene Properties > Camera")
    layer = _pick_layer(scene, view_layer)
    materials = sss_materials(scene)
    if not materials:
        raise NoSubsurfaceError(
            f"scene {scene.name!r} has no material with subsurface scattering (Subsurface Weight > 0, "
            "a Subsurface Radius and Scale above 0): nothing to render"
        )
    for m in materials:  # what the reader could not read as Cycles renders it
        for note in m.notes:
            say(f"{printable(m.name)}: {printable(note)}")
    if scene.render.use_border:
        say(
            "the scene's render region (Render Region, Output Properties > Format) is left out: the passes cover"
            " the whole frame, as the techniques gather light from around each pixel and the scene"
            " description's camera is the whole frame's"
        )
    aov_name = thickness_aov_name(scene)
    convention = "translucency"
    needs_thickness = any(aov_name in required_passes(t, aov_name) for t in techniques)
    if needs_thickness:
        convention, without = thickness_setup(scene, materials, aov_name)
        if without:
            say(f"no thickness map in {', '.join(repr(n) for n in without)}: STA reads thickness 0 there")
    assert convention in CONVENTIONS
    input_aovs = input_aovs_of(materials)
    names = needed_passes(techniques, aov_name) + [a.name for a in input_aovs]
    out_dir, targets = _targets(out_dir, frames, overwrite)
    return _Plan(
        techniques, layer, materials, aov_name, needs_thickness, convention, names, out_dir, targets, input_aovs
    )


def _set_up(st: SceneState, scene, plan: _Plan, *, samples, seed, res, say) -> dict[str, int]:
    """Put ``scene`` in the render state of the module's docstring, through ``st``; returns the
    objects given a Pass Index for the Object Index pass."""
    render = scene.render
    cycles = scene.cycles
    layer = plan.layer
    old_frame, old_subframe = scene.frame_current, scene.frame_subframe
    st.on_restore(lambda: scene.frame_set(old_frame, subframe=old_subframe))
    st.set(render, "engine", "CYCLES")
    if samples is not None:
        st.set(cycles, "samples", samples)
    if seed is not None:
        st.set(cycles, "seed", seed)
    for attr, value in (("use_adaptive_sampling", False), ("use_denoising", False), ("time_limit", 0.0)):
        if getattr(cycles, attr) != value:
            st.set(cycles, attr, value)
    if res is not None:
        st.set(render, "resolution_x", res[0])
        st.set(render, "resolution_y", res[1])
        st.set(render, "resolution_percentage", 100)
    for attr in ("use_compositing", "use_sequencer", "use_single_layer", "use_border"):
        if getattr(render, attr):
            st.set(render, attr, False)
    for vl in scene.view_layers:
        if vl.use != (vl == layer):
            st.set(vl, "use", vl == layer)
    wanted = [(plan.aov_name, "VALUE")] if plan.needs_thickness else []
    _set_passes(st, scene, layer, plan.names, wanted + [(a.name, a.kind) for a in plan.input_aovs])
    wire_input_aovs(st, plan.materials)  # before zero_subsurface cuts the Weight's link
    zero_subsurface(st, scene)
    _material_indices(st, scene, plan.materials)
    assigned = _object_indices(st, scene) if "Object Index" in plan.names else {}
    if assigned:
        say(f"objects without a Pass Index got one for the Object Index pass: {assigned}")
    image_settings = render.image_settings
    fmt = compat.image_format_state(image_settings)
    st.on_restore(lambda: compat.restore_image_format(image_settings, fmt))
    compat.set_multilayer_exr(image_settings)
    return assigned


def _render_frame(scene, frame: int, exr: str, plan: _Plan) -> None:
    """Render the current frame and write its passes to ``exr`` (a temporary file beside it, read
    back and checked, then moved into place)."""
    _render(scene)
    result = bpy.data.images.get("Render Result")
    if result is None:
        raise RuntimeError(f"frame {frame}: Blender produced no Render Result")
    with files.temporary_beside(exr, suffix=os.path.splitext(exr)[1]) as tmp:
        try:
            result.save_render(filepath=tmp, scene=scene)
            if os.path.getsize(tmp) == 0:
                raise RuntimeError(f"frame {frame}: Blender did not write {tmp}")
            verify_passes(tmp, plan.names, plan.layer.name, [m.index for m in plan.materials])
        except (RuntimeError, DamagedFileError) as exc:
            # Blender's saver leaves a short file on a full disk instead of failing.
            if files.disk_full(tmp):
                raise files.write_failure(exr, exc) from None
            raise
        files.move_into_place(tmp, exr)


def render_passes_job(
    scene,
    out_dir: str,
    *,
    techniques: Iterable[str] = tuple(TECHNIQUES),
    frames: Iterable[int] | None = None,
    samples: int | None = None,
    resolution=None,
    seed: int | None = None,
    view_layer=None,
    overwrite: bool = False,
    log: Callable[[str], None] | None = print,
) -> Job:
    """Render the passes ``techniques`` need for each frame into ``out_dir``: a job generator
    (``blender/jobs.py``) with one step per frame; Render Passes runs it modal.

    Writes ``passes_####.exr`` (multilayer, float32) and ``passes_####.json`` (the scene
    description, ``core.pipeline.sequence.sidecar_path``) per frame and returns the paths written, EXR then
    JSON per frame. ``frames``: frame numbers (default: the current frame). ``samples``,
    ``seed``: Cycles samples and seed (default: the scene's). ``resolution``: ``"WxH"`` or
    (W, H) rendered at 100 % (default: the scene's). ``view_layer``: name or ViewLayer
    (default: the active one). Existing files are not replaced unless ``overwrite``.

    Raises NoSubsurfaceError (a ValueError) when no material scatters, ValueError for bad
    arguments or a scene it cannot render as asked (no camera, STA without a thickness map),
    FileExistsError before rendering when a file exists. The scene is restored in every case.
    """
    techniques = _check_techniques(techniques)
    _check_numbers(samples, seed)
    res = parse_resolution(resolution) if resolution is not None else None
    say = log or (lambda _line: None)
    plan = _plan(
        scene, out_dir, techniques=techniques, frames=frames, view_layer=view_layer, overwrite=overwrite, say=say
    )
    targets = plan.targets
    # Checked and planned; nothing has changed yet.
    yield Progress(0, len(targets), f"frame {targets[0][0]}")
    try:
        os.makedirs(plan.out_dir, exist_ok=True)
    except OSError as exc:
        raise OutputError(exc.errno, describe_os_error(exc, plan.out_dir)) from None

    written: list[str] = []
    render = scene.render
    cycles = scene.cycles
    with SceneState() as st:
        assigned = _set_up(st, scene, plan, samples=samples, seed=seed, res=res, say=say)
        meta = {
            "techniques": list(techniques),
            "passes": plan.names,
            "samples": int(cycles.samples),
            "seed": int(cycles.seed),
            "view_layer": plan.layer.name,
            "object_pass_index_assigned": assigned,
        }
        for number, (frame, exr) in enumerate(targets, 1):
            scene.frame_set(frame)
            description = describe_scene(
                scene,
                plan.materials,
                thickness_aov=plan.aov_name,
                thickness_convention=plan.convention,
                meta=dict(meta),
            )
            say(
                f"[{number}/{len(targets)}] frame {frame}: rendering {', '.join(plan.names)} "
                f"({render.resolution_x * render.resolution_percentage // 100}x"
                f"{render.resolution_y * render.resolution_percentage // 100}, {cycles.samples} samples)"
            )
            t0 = time.perf_counter()
            _render_frame(scene, frame, exr, plan)
            written.append(exr)
            say(saved_line(exr))
            json_path = sidecar_path(exr)
            files.write_text(json_path, description.to_json())
            written.append(json_path)
            say(saved_line(json_path))
            say(f"frame {frame} done in {time.perf_counter() - t0:.2f} s")
            if number < len(targets):  # between frames: a modal run may stop here (Esc)
                yield Progress(number, len(targets), f"frame {targets[number][0]}", tuple(written))
    return written


def resolve_folder(path: str) -> str:
    """An absolute folder from a Blender path (``//`` = beside the .blend file)."""
    if not path:
        raise ValueError("output folder: empty; choose a folder for the passes")
    if path.startswith("//") and not bpy.data.filepath:
        raise ValueError(
            f"output folder {path!r} is relative to the .blend file, which is not saved yet; save it or choose "
            "an absolute folder"
        )
    return os.path.abspath(bpy.path.abspath(path))
