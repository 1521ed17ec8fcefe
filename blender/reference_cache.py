"""The Cycles reference of ``compare``, rendered once per state of the scene.

``cached_reference`` renders the scene's Combined image with fixed settings and keeps it on disk
under a key made of ``scene_fingerprint`` (a hash of everything the picture depends on) and the
render settings, so that a second comparison of an unchanged scene does not render it again.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import struct
import time
from typing import Any

import bpy
import numpy as np

from ..core.base import files, memory
from ..core.base.jsonfile import read_json
from ..core.scene import exr
from . import compat
from .describe import principled_node, scene_materials
from .state import SceneState


def _hash_floats(h, values) -> None:
    h.update(struct.pack(f"<{len(values)}d", *values))


def scene_fingerprint(scene) -> str:
    """A hash of what the rendered image depends on: evaluated geometry, transforms, materials,
    lights, camera, world and render settings. A change to any of these changes the hash."""
    h = hashlib.sha256()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    # Instances are only valid while iterating: hash each into its own digest, then combine the
    # digests in a stable order.
    parts = []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.hide_render:
            continue
        p = hashlib.sha256()
        p.update(f"{obj.type}:{obj.name}:{obj.pass_index}".encode())
        _hash_floats(p, [v for row in inst.matrix_world for v in row])
        if obj.type == "MESH":
            # The original mesh and its modifier stack, not the evaluated mesh, and its faces in
            # a canonical order: a mesh built by script can number its edges and faces otherwise
            # on each run (bmesh's UV sphere follows memory addresses; the sample scenes'
            # ``_canonical``), and Subdivision Surface numbers its output vertices after them,
            # which would make every run a new reference.
            original = obj.original
            mesh = original.data
            co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
            mesh.vertices.foreach_get("co", co)
            p.update(co.tobytes())
            p.update(_topology_digest(mesh))
            for attr in mesh.attributes:
                p.update(f"attr:{attr.name}:{attr.domain}:{attr.data_type}".encode())
            p.update(",".join(m.name if m else "" for m in mesh.materials).encode())
            if mesh.shape_keys is not None:
                for key in mesh.shape_keys.key_blocks:
                    _hash_floats(p, [key.value])
                    kco = np.empty(len(key.data) * 3, dtype=np.float32)
                    key.data.foreach_get("co", kco)
                    p.update(kco.tobytes())
            for modifier in original.modifiers:
                _hash_rna(p, modifier)
        elif obj.type == "ARMATURE":
            for bone in obj.pose.bones:
                _hash_floats(p, [v for row in bone.matrix for v in row])
        elif obj.type == "LIGHT":
            d = obj.data
            p.update(f"{d.type}".encode())
            _hash_floats(
                p,
                [
                    d.energy,
                    *d.color,
                    getattr(d, "shadow_soft_size", 0.0),
                    getattr(d, "spot_size", 0.0),
                    getattr(d, "spot_blend", 0.0),
                    getattr(d, "size", 0.0),
                    getattr(d, "angle", 0.0),
                ],
            )
        elif obj.type == "CAMERA":
            d = obj.data
            p.update(f"{d.type}:{d.sensor_fit}".encode())
            _hash_floats(
                p,
                [
                    d.lens,
                    d.sensor_width,
                    d.sensor_height,
                    d.ortho_scale,
                    d.clip_start,
                    d.clip_end,
                    d.shift_x,
                    d.shift_y,
                ],
            )
        parts.append(p.digest())
    for digest in sorted(parts):
        h.update(digest)
    for mat in scene_materials(scene):
        _hash_node_tree(h, mat.node_tree)
    if scene.world is not None and scene.world.node_tree is not None:
        _hash_node_tree(h, scene.world.node_tree)
    r = scene.render
    h.update(f"{r.engine}:{r.resolution_x}:{r.resolution_y}:{r.resolution_percentage}:{r.film_transparent}".encode())
    h.update(f"{scene.camera.name if scene.camera else ''}:{bpy.app.version_string}".encode())
    return h.hexdigest()


def _topology_digest(mesh) -> bytes:
    """The mesh's faces as sets of vertex indices, in a canonical order: the same faces listed in
    another order (or starting at another corner) give the same digest."""
    loops = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", loops)
    starts = np.empty(len(mesh.polygons), dtype=np.int64)
    totals = np.empty(len(mesh.polygons), dtype=np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", totals)
    if not starts.size:
        return b"no faces"
    width = int(totals.max())
    corner = np.arange(width)[None, :]
    faces = np.where(corner < totals[:, None], loops[np.minimum(starts[:, None] + corner, loops.size - 1)], -1)
    faces.sort(axis=1)
    faces = faces[np.lexsort(faces.T[::-1])]
    return hashlib.sha256(faces.tobytes()).digest()


def _hash_rna(h, struct) -> None:
    """Hash the editable RNA properties of ``struct`` (a modifier): numbers, enums, strings, the
    names of the IDs it points to, and its custom properties (geometry-node inputs)."""
    h.update(struct.bl_rna.identifier.encode())
    for prop in struct.bl_rna.properties:
        if prop.is_readonly or prop.identifier == "rna_type" or prop.type == "COLLECTION":
            continue
        value: Any = getattr(struct, prop.identifier, None)
        if prop.type == "POINTER":
            value = getattr(value, "name", None)
        elif hasattr(value, "__len__") and not isinstance(value, str):
            value = list(value)
        h.update(f"{prop.identifier}={value!r};".encode())
    try:
        keys = list(struct.keys())
    except TypeError:  # this kind of modifier holds no custom properties
        keys = []
    for key in keys:
        value = struct[key]
        h.update(f"[{key}]={getattr(value, 'name', value)!r};".encode())


def _hash_node_tree(h, tree) -> None:
    if tree is None:
        return
    for node in sorted(tree.nodes, key=lambda n: n.name):
        h.update(f"node:{node.name}:{node.bl_idname}".encode())
        for prop in ("subsurface_method", "distribution", "blend_type", "operation", "data_type"):
            if hasattr(node, prop):
                h.update(f"{prop}={getattr(node, prop)}".encode())
        for sock in node.inputs:
            value = getattr(sock, "default_value", None)
            if value is None:
                continue
            try:
                floats = [float(v) for v in value] if hasattr(value, "__len__") else [float(value)]
                _hash_floats(h, floats)
            except (TypeError, ValueError):
                h.update(str(value).encode())
    for link in tree.links:
        h.update(
            f"link:{link.from_node.name}.{link.from_socket.identifier}->"
            f"{link.to_node.name}.{link.to_socket.identifier}".encode()
        )


def render_combined(
    scene, *, samples: int, seed: int, resolution, path: str, state: SceneState, denoise: bool = False
) -> float:
    """Render ``scene`` with Cycles to a float32 multilayer EXR at ``path``; returns seconds. With
    ``denoise`` the image is denoised by OpenImageDenoise (albedo and normal as guides, prefiltered),
    as a user wanting a quick faithful picture renders it."""
    cy = scene.cycles
    state.set(scene.render, "engine", "CYCLES")
    # Cycles' own image: no compositor (SSS Lab's node groups there would change the materials and the image).
    state.set(scene.render, "use_compositing", False)
    state.set(cy, "samples", samples)
    state.set(cy, "seed", seed)
    state.set(cy, "use_adaptive_sampling", False)
    state.set(cy, "use_animated_seed", False)
    state.set(cy, "use_denoising", bool(denoise))
    if denoise:
        state.set(cy, "denoiser", "OPENIMAGEDENOISE")
        state.set(cy, "denoising_input_passes", "RGB_ALBEDO_NORMAL")
        state.set(cy, "denoising_prefilter", "ACCURATE")
    if scene.render.use_border:  # the whole frame, as the passes it is compared with
        state.set(scene.render, "use_border", False)
    if resolution is not None:
        state.set(scene.render, "resolution_x", resolution[0])
        state.set(scene.render, "resolution_y", resolution[1])
        state.set(scene.render, "resolution_percentage", 100)
    r = scene.render
    # The image and, when denoising, its albedo and normal guides.
    channels = 4 + (6 if denoise else 0)
    memory.check_frame(
        r.resolution_x * r.resolution_percentage // 100,
        r.resolution_y * r.resolution_percentage // 100,
        channels,
        "the Cycles render",
    )
    start = time.perf_counter()
    bpy.ops.render.render(scene=scene.name)
    seconds = time.perf_counter() - start
    settings = scene.render.image_settings
    fmt = compat.image_format_state(settings)
    state.on_restore(lambda: compat.restore_image_format(settings, fmt))
    compat.set_multilayer_exr(settings)
    bpy.data.images["Render Result"].save_render(filepath=path, scene=scene)
    return seconds


def _with_method(scene, method: str, state: SceneState) -> None:
    """Switch every subsurface material's method to ``method`` (restored by ``state``)."""
    for mat in scene_materials(scene):
        node = principled_node(mat)
        if node is not None and node.inputs["Subsurface Weight"].default_value > 0:
            state.set(node, "subsurface_method", compat.subsurface_method_item(method))


def cached_reference(
    scene,
    cache_dir: str,
    *,
    samples: int,
    seed: int,
    resolution,
    method: str | None,
    log=print,
    fingerprint: str | None = None,
    denoise: bool = False,
) -> tuple[np.ndarray, float, bool]:
    """The Cycles image for these settings, from the cache when the scene has not changed.

    ``fingerprint``: the scene's ``scene_fingerprint``, when the caller already has it (it hashes
    every mesh). Returns (RGBA float32 image, render seconds (as measured when it was rendered),
    from cache).
    """
    fingerprint = fingerprint or scene_fingerprint(scene)
    parts: list = [fingerprint, samples, seed, list(resolution or []), method]
    if denoise:  # a key of its own; the undenoised entries keep theirs
        parts.append("oidn")
    key = hashlib.sha256(json.dumps(parts).encode()).hexdigest()[:24]
    path = os.path.join(cache_dir, f"cycles_{key}.exr")
    meta_path = path[:-4] + ".json"
    cached = read_cached_image(
        path, meta_path, log, expect={"samples": samples, "seed": seed, "method": method}, size=resolution
    )
    what = f"Cycles {method or 'scene method'} {samples} samples seed {seed}" + (", denoised" if denoise else "")
    if cached is not None:
        log(f"{what}: cached ({os.path.basename(path)})")
        return cached[0], cached[1], True
    log(f"{what}: rendering")
    with SceneState() as state:
        if method is not None:
            _with_method(scene, method, state)
        with files.temporary_beside(path, suffix=".exr") as tmp:
            seconds = render_combined(
                scene, samples=samples, seed=seed, resolution=resolution, path=tmp, state=state, denoise=denoise
            )
            try:
                image = exr.read_passes(tmp)["Combined"]
            except (exr.DamagedFileError, exr.MissingPassError) as exc:
                if files.disk_full(tmp):
                    raise files.write_failure(path, exc) from None
                raise
            files.move_into_place(tmp, path)
    # The metadata last, atomically: an entry without it is rendered again, never half-read.
    meta = {"seconds": seconds, "samples": samples, "seed": seed, "method": method, "denoise": bool(denoise)}
    files.write_text(meta_path, json.dumps(meta))
    return image, seconds, False


#: The longest render a cache entry may claim (a week): beyond it the metadata is damaged.
MAX_CACHED_SECONDS = 7 * 24 * 3600.0


def read_cached_image(
    path: str, meta_path: str, log, *, expect: dict | None = None, size=None
) -> tuple[np.ndarray, float] | None:
    """(image, render seconds) of a cache entry; None when there is none, or with a note when
    it cannot be read or is not what the key stands for: an empty or damaged metadata file, render
    seconds that are not a number in 0..``MAX_CACHED_SECONDS``, a value of ``expect`` (what was
    asked for: samples, seed, ...) that differs, a truncated EXR, pixels that are not finite (a
    render's are), an image of another ``size`` (width, height). It is then rendered again."""
    if not (os.path.isfile(path) and os.path.isfile(meta_path)):
        return None
    try:
        meta = read_json(meta_path, "the metadata of a cached reference")
        if not isinstance(meta, dict):
            raise ValueError(f"the metadata is a {type(meta).__name__}, not an object")
        seconds = meta["seconds"]
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not math.isfinite(seconds):
            raise ValueError(f"'seconds' is {seconds!r}, not a number")
        if not 0 <= seconds <= MAX_CACHED_SECONDS:
            raise ValueError(f"'seconds' is {seconds!r}, not a render time (0..{MAX_CACHED_SECONDS:g})")
        for key, value in (expect or {}).items():
            if key in meta and meta[key] != value:
                raise ValueError(f"{key!r} is {meta[key]!r} where the entry's key stands for {value!r}")
        image = exr.read_passes(path)["Combined"]
        if size is not None and tuple(image.shape[1::-1]) != tuple(size):
            raise ValueError(f"the image is {image.shape[1]}x{image.shape[0]}, not {size[0]}x{size[1]}")
        if not np.all(np.isfinite(image)):
            raise ValueError(f"{int(np.count_nonzero(~np.isfinite(image)))} values are not finite")
    except (OSError, ValueError, KeyError, TypeError) as exc:  # JSONDecodeError and UnicodeError are ValueErrors
        reason = " ".join(str(exc.args[0] if isinstance(exc, KeyError) and exc.args else exc).split())[:200]
        log(f"note: the cached reference {path} cannot be used ({reason}); rendering it again")
        return None
    return image, float(seconds)
