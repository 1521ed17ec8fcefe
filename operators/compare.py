"""Compare each technique with Cycles' random-walk SSS on the user's own scene.

``compare(scene, out_dir)`` renders

- the reference: the scene as it is (its own subsurface method, normally Random Walk), fixed
  seed, adaptive sampling off (docs/references.md §8), cached by a fingerprint of the scene
  and the settings so that a second run of an unchanged scene does not render it again;
- the noise floor: the same reference with another seed, compared with the same metric;
- peers: Cycles at lower sample counts, and Cycles' own Christensen-Burley method;
- the passes the techniques need (``render_passes``: SSS rendered as plain diffuse);

then applies every technique at several quality settings with ``core.apply``, and writes the
report (``core.report``): metrics.json, report.md, report.html, grid.png, pareto.svg.

The scene is left as it was (``SceneState``), also when a step fails.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import struct
import tempfile
import time
from dataclasses import asdict, dataclass, field

import bpy
import numpy as np

from ..addon import compat
from ..core import apply as core_apply
from ..core import exr, fidelity, mapping, metrics, report
from ..core.scene import SUBSURFACE_METHODS, SceneDescription
from ..core.techniques import TECHNIQUES, check_technique
from .describe import principled_node, scene_materials, sss_materials
from .state import SceneState

#: Quality ladders: the keyword arguments each technique is run with, cheapest first.
DEFAULT_QUALITIES: dict[str, tuple[dict, ...]] = {
    "sta": ({}, {"falloff": "burley"}),
    "ssss": ({"n_taps": 11}, {"n_taps": 17}, {"n_taps": 25}),
    "burley": ({"n_samples": 8}, {"n_samples": 16}, {"n_samples": 32}, {"n_samples": 64}),
    "combined": ({"diffusion": "ssss", "n_taps": 11}, {"n_samples": 16}, {"n_samples": 32}),
}


#: STA scales s_T and thickness falloffs the calibration tries (STA_DEFAULTS: 1, the map).
STA_SCALES = (0.25, 0.5, 1.0, 2.0, 4.0)
STA_FALLOFFS = ("map", "burley")


@dataclass
class CompareSettings:
    """What ``compare`` renders and measures. Resolution None keeps the scene's."""

    resolution: tuple[int, int] | None = None
    reference_samples: int = 256
    pass_samples: int = 64
    seed: int = 0
    peer_samples: tuple[int, ...] = (16, 64)
    cycles_burley: bool = True
    box: int = 2
    techniques: tuple[str, ...] = tuple(TECHNIQUES)
    qualities: dict = field(default_factory=lambda: dict(DEFAULT_QUALITIES))
    cache_dir: str | None = None
    #: Other subsurface methods to calibrate the mapping for: the reference is rendered again with
    #: the scene's subsurface materials switched to each (cached like the others).
    calibrate_methods: tuple[str, ...] = ()

    def validate(self) -> None:
        for name in ("reference_samples", "pass_samples", "box"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ValueError(f"{name}: expected an integer >= 1, got {v!r}")
        if any(not isinstance(s, int) or s < 1 for s in self.peer_samples):
            raise ValueError(f"peer_samples: expected integers >= 1, got {self.peer_samples!r}")
        if self.resolution is not None:
            w, h = self.resolution
            if not (isinstance(w, int) and isinstance(h, int) and w >= 1 and h >= 1):
                raise ValueError(f"resolution: expected two integers >= 1 (W, H), got {self.resolution!r}")
        for t in self.techniques:
            check_technique(t)
        for m in self.calibrate_methods:
            if m not in SUBSURFACE_METHODS:
                raise ValueError(f"calibrate_methods: unknown subsurface method {m!r}; expected: {SUBSURFACE_METHODS}")


# --- The reference cache -------------------------------------------------------------------


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
            # The original mesh and its modifier stack, not the evaluated mesh: modifiers such as
            # Subdivision Surface number their output vertices differently from run to run
            # (threads), which would make every run a new reference.
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
        value = getattr(struct, prop.identifier, None)
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


# --- Rendering -------------------------------------------------------------------------------


def _render_combined(scene, *, samples: int, seed: int, resolution, path: str, state: SceneState) -> float:
    """Render ``scene`` with Cycles to a float32 multilayer EXR at ``path``; returns seconds."""
    cy = scene.cycles
    state.set(scene.render, "engine", "CYCLES")
    # Cycles' own image: no compositor (SSS Lab's node groups there would change the materials and the image).
    state.set(scene.render, "use_compositing", False)
    state.set(cy, "samples", samples)
    state.set(cy, "seed", seed)
    state.set(cy, "use_adaptive_sampling", False)
    state.set(cy, "use_animated_seed", False)
    state.set(cy, "use_denoising", False)
    if resolution is not None:
        state.set(scene.render, "resolution_x", resolution[0])
        state.set(scene.render, "resolution_y", resolution[1])
        state.set(scene.render, "resolution_percentage", 100)
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
            state.set(node, "subsurface_method", method)


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
) -> tuple[np.ndarray, float, bool]:
    """The Cycles image for these settings, from the cache when the scene has not changed.

    ``fingerprint``: the scene's ``scene_fingerprint``, when the caller already has it (it hashes
    every mesh). Returns (RGBA float32 image, render seconds (as measured when it was rendered),
    from cache).
    """
    fingerprint = fingerprint or scene_fingerprint(scene)
    key = hashlib.sha256(json.dumps([fingerprint, samples, seed, list(resolution or []), method]).encode()).hexdigest()[
        :24
    ]
    path = os.path.join(cache_dir, f"cycles_{key}.exr")
    meta_path = path[:-4] + ".json"
    if os.path.isfile(path) and os.path.isfile(meta_path):
        with open(meta_path, encoding="utf-8") as fh:
            seconds = json.load(fh)["seconds"]
        log(f"Cycles {method or 'scene method'} {samples} samples seed {seed}: cached ({os.path.basename(path)})")
        return exr.read_passes(path)["Combined"], seconds, True
    os.makedirs(cache_dir, exist_ok=True)
    log(f"Cycles {method or 'scene method'} {samples} samples seed {seed}: rendering")
    with SceneState() as state:
        if method is not None:
            _with_method(scene, method, state)
        fd, tmp = tempfile.mkstemp(dir=cache_dir, suffix=".exr")
        os.close(fd)
        try:
            seconds = _render_combined(scene, samples=samples, seed=seed, resolution=resolution, path=tmp, state=state)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.remove(tmp)
    with open(meta_path, "w", encoding="utf-8") as fh:
        json.dump({"seconds": seconds, "samples": samples, "seed": seed, "method": method}, fh)
    return exr.read_passes(path)["Combined"], seconds, False


# --- The comparison ---------------------------------------------------------------------------


def _quality_label(technique: str, quality: dict) -> str:
    label = TECHNIQUES[technique][2]
    if not quality:
        return label
    return label + " " + ", ".join(f"{k.replace('n_', '')}={v}" for k, v in quality.items())


def compare(scene, out_dir: str, settings: CompareSettings | None = None, *, log=print) -> dict:
    """Run the whole comparison and write the report into ``out_dir``; returns the report data.

    Raises ValueError for a scene without a camera or without subsurface materials (nothing to
    compare). A technique that cannot run on this scene (e.g. a subsurface method the mapping
    does not know, or STA without a thickness map) is noted in the report, which then says it
    is incomplete.
    """
    from .render_passes import render_passes

    settings = settings or CompareSettings()
    settings.validate()
    if scene.camera is None:
        raise ValueError(f"scene {scene.name!r} has no active camera; set one in Scene Properties > Camera")
    materials = sss_materials(scene)
    if not materials:
        raise ValueError(
            f"scene {scene.name!r} has no material with subsurface scattering (Subsurface Weight > 0):"
            " nothing to compare"
        )
    notes: list[str] = []
    techniques = tuple(settings.techniques)
    needs_thickness = tuple(t for t in techniques if core_apply.THICKNESS in core_apply.REQUIRED_PASSES[t])
    if needs_thickness:
        from .render_passes import thickness_aov_name, thickness_setup

        try:
            thickness_setup(scene, materials, thickness_aov_name(scene))
        except ValueError as exc:
            # Checked before anything renders: the other techniques still get their report.
            techniques = tuple(t for t in techniques if t not in needs_thickness)
            for t in needs_thickness:  # one note per technique, each by its label
                notes.append(f"{TECHNIQUES[t][2]} not run: {exc}")
                log(notes[-1])
            if not techniques:
                raise
        settings = dataclasses.replace(settings, techniques=techniques)
    os.makedirs(out_dir, exist_ok=True)
    cache_dir = settings.cache_dir or os.path.join(out_dir, "cache")
    timings: dict[str, float] = {}
    res = settings.resolution

    fingerprint = scene_fingerprint(scene)
    # Every Cycles image of this comparison: same scene, folder and size; samples, seed and method vary.
    reference = functools.partial(cached_reference, scene, cache_dir, resolution=res, log=log, fingerprint=fingerprint)
    ref, ref_seconds, _ = reference(samples=settings.reference_samples, seed=settings.seed, method=None)
    second, _, _ = reference(samples=settings.reference_samples, seed=settings.seed + 1, method=None)
    images: dict[str, np.ndarray] = {}
    entries: list[dict] = []

    log(f"Passes: {settings.pass_samples} samples, subsurface as plain diffuse")
    passes_dir = os.path.join(out_dir, "passes")
    start = time.perf_counter()
    written = render_passes(
        scene,
        passes_dir,
        techniques=settings.techniques,
        samples=settings.pass_samples,
        resolution=res,
        seed=settings.seed,
        overwrite=True,
        log=log,
    )
    timings["passes"] = time.perf_counter() - start
    exr_path = next(p for p in written if p.endswith(".exr"))
    passes = exr.read_passes(exr_path)
    desc: SceneDescription = core_apply.load_scene(exr_path)
    index = np.rint(np.nan_to_num(passes["Material Index"])).astype(np.int64)
    if index.ndim == 3:
        index = index[..., 0]
    mask = np.isin(index, [m.index for m in desc.materials if m.scatters])
    if ref.shape[:2] != mask.shape:
        raise ValueError(f"reference {ref.shape[:2]} and passes {mask.shape} differ in size")

    def add(name, kind, image, total, apply_s=None, extra=None):
        m = metrics.compare_images(image, ref, mask, box=settings.box)
        entry = {"name": name, "kind": kind, "metrics": m, "time_s": {"total": total, "apply": apply_s}}
        entry.update(extra or {})
        entries.append(entry)
        images[name] = image
        log(f"  {name}: rel. RMSE {m['rel_rmse']:.4f}, SSIM {m['ssim']:.4f}, {total:.2f} s")

    add("no SSS", "baseline", passes["Combined"], timings["passes"])
    for technique in settings.techniques:
        for quality in settings.qualities.get(technique, ({},)):
            label = _quality_label(technique, quality)
            try:
                start = time.perf_counter()
                layers = core_apply.apply(passes, desc, technique, **quality)
                apply_s = time.perf_counter() - start
            except (ValueError, KeyError) as exc:
                notes.append(f"{label} did not run: {exc}")
                log(f"  {label}: not run ({exc})")
                continue
            if not layers:
                notes.append(f"{label}: no material scattered on screen")
                continue
            image = layers[core_apply.layer_names(technique)[0]]
            add(
                label,
                "technique",
                image,
                timings["passes"] + apply_s,
                apply_s,
                {"technique": technique, "quality": quality},
            )

    for samples in settings.peer_samples:
        if samples >= settings.reference_samples:
            continue
        img, secs, _ = reference(samples=samples, seed=settings.seed + 2, method=None)
        add(f"Cycles {samples} spp", "cycles", img, secs)
    if settings.cycles_burley:
        img, secs, _ = reference(samples=settings.reference_samples, seed=settings.seed + 3, method="BURLEY")
        add(f"Cycles Christensen-Burley {settings.reference_samples} spp", "cycles", img, secs)

    images["Cycles reference"] = ref
    noise = metrics.compare_images(second, ref, mask, box=settings.box)
    data = {
        "scene": {
            "name": _scene_label(scene),
            "file": bpy.data.filepath,
            "materials": [asdict(m) for m in desc.materials],
            "fingerprint": fingerprint,
        },
        "settings": {
            "resolution": list(ref.shape[1::-1]),
            "reference_samples": settings.reference_samples,
            "reference_seconds": ref_seconds,
            "pass_samples": settings.pass_samples,
            "seed": settings.seed,
            "box": settings.box,
            "reference_method": "scene's own subsurface method ("
            + ", ".join(sorted({m.method for m in materials}))
            + ")",
            "blender": bpy.app.version_string,
        },
        "noise_floor": noise,
        "timings": timings,
        "entries": entries,
        "fidelity": _fidelity(desc, settings.techniques, notes),
        "calibration": _calibration(settings, passes, desc, ref, mask, reference),
        "notes": notes,
        "complete": not notes,
    }
    order = (
        ["no SSS"]
        + [e["name"] for e in entries if e["kind"] == "technique"]
        + [e["name"] for e in entries if e["kind"] == "cycles"]
        + ["Cycles reference"]
    )
    out = report.write_report(
        out_dir, data, images, reference="Cycles reference", mask=mask, order=order, summary=_summary(order, entries)
    )
    log(f"Saved: {os.path.join(out_dir, 'report.html')}")
    return out


def _summary(order: list[str], entries: list[dict]) -> list[str]:
    """Columns of summary.png: no SSS, each technique at its default quality (or its last), the
    reference."""
    defaults = {
        "sta": {},
        "ssss": {"n_taps": mapping.SSSS_DEFAULTS["n_taps"]},
        "burley": {"n_samples": mapping.BURLEY_DEFAULTS["n_samples"]},
        "combined": {"n_samples": mapping.COMBINED_DEFAULTS["n_samples"]},
    }
    picked = ["no SSS"]
    for technique in TECHNIQUES:
        runs = [e for e in entries if e.get("technique") == technique]
        if runs:
            best = [e for e in runs if e.get("quality") == defaults[technique]]
            picked.append((best or runs)[-1]["name"])
    return [n for n in picked if n in order] + ["Cycles reference"]


def _scene_label(scene) -> str:
    """``file.blend / Scene``, or the scene's name alone for an unsaved file."""
    path = bpy.data.filepath
    return f"{os.path.basename(path)} / {scene.name}" if path else scene.name


def _fidelity(desc: SceneDescription, techniques, notes: list) -> dict | None:
    try:
        return fidelity.fidelity_table(_main_material(desc), techniques=techniques)
    except ValueError as exc:
        notes.append(f"fidelity table not measured: {exc}")
        return None


def _main_material(desc: SceneDescription):
    """The scattering material the fidelity table is measured with: the one with the widest radius."""
    return max((m for m in desc.materials if m.scatters), key=lambda m: max(m.radius))


def _mark_best(results: list[dict]) -> None:
    """Mark the row with the lowest error chosen, unless all are equal to 1e-4 relative (the
    technique did not change this scene, e.g. STA without light from behind): then none is."""
    errors = [r["rel_rmse"] for r in results if r.get("rel_rmse") is not None]
    if not errors or max(errors) - min(errors) <= 1e-4 * max(min(errors), 1e-12):
        return
    min((r for r in results if r.get("rel_rmse") is not None), key=lambda r: r["rel_rmse"])["chosen"] = True


def _calibration(settings: CompareSettings, passes, desc: SceneDescription, ref, mask, reference):
    """The scene's own methods against its reference, then each method of
    ``settings.calibrate_methods`` against a reference rendered with it (``reference``: the
    comparison's ``cached_reference`` with the scene and size bound)."""
    result = calibrate(passes, desc, ref, mask, box=settings.box, techniques=settings.techniques)
    own = {m.method for m in desc.materials if m.scatters}
    scattering = tuple(t for t in settings.techniques if t != "sta")
    for method in settings.calibrate_methods:
        if method in own or not scattering:
            continue
        method_ref, _, _ = reference(samples=settings.reference_samples, seed=settings.seed, method=method)
        as_method = dataclasses.replace(
            desc,
            materials=tuple(dataclasses.replace(m, method=method) if m.scatters else m for m in desc.materials),
        )
        base = metrics.compare_images(passes["Combined"], method_ref, mask, box=settings.box)
        result["rows"].append({"method": method, "technique": "no SSS", "mapping": "-", "rel_rmse": base["rel_rmse"]})
        result["rows"] += calibrate(passes, as_method, method_ref, mask, box=settings.box, techniques=scattering)[
            "rows"
        ]
    return result


def _sweep(passes, desc, ref, mask, box: int, technique: str, method: str, variants) -> list[dict]:
    """Rows for ``technique`` run with each (label, options) of ``variants``: the ones that could
    not run (with the reason), then the measured ones, the best marked chosen."""
    failed, results = [], []
    for label, options in variants:
        row = {"method": method, "technique": technique, "mapping": label}
        try:
            layers = core_apply.apply(passes, desc, technique, **options)
        except (ValueError, KeyError) as exc:
            failed.append({**row, "rel_rmse": None, "error": str(exc)})
            continue
        if layers:
            m = metrics.compare_images(layers[core_apply.layer_names(technique)[0]], ref, mask, box=box)
            results.append({**row, "rel_rmse": m["rel_rmse"]})
    _mark_best(results)
    return failed + results


def calibrate(passes, desc: SceneDescription, ref, mask, *, box: int, techniques) -> dict:
    """For each subsurface method in the scene and each scattering technique, the error of
    every mapping the core offers; the lowest is marked chosen (none when all are equal)."""
    rows = []
    for method in sorted({m.method for m in desc.materials if m.scatters}):
        for technique in [t for t in techniques if t in ("ssss", "burley")]:
            variants = [(name, {"mapping": name}) for name in mapping.MAPPINGS.get(method, ())]
            rows += _sweep(passes, desc, ref, mask, box, technique, method, variants)
    if "sta" in techniques:
        # STA has no physical scale (core/mapping.py): its scale s_T is what there is to calibrate,
        # with each thickness falloff.
        variants = [
            (f"{falloff}, scale={scale:g}", {"scale": scale, "falloff": falloff})
            for falloff in STA_FALLOFFS
            for scale in STA_SCALES
        ]
        rows += _sweep(passes, desc, ref, mask, box, "sta", "any", variants)
    return {
        "definition": "Each mapping from the Principled BSDF inputs to the technique's parameters (core/mapping.py),"
        " applied to this scene's passes, and STA's scale s_T; relative RMSE against the reference as above.",
        "rows": rows,
    }


class SSS_LAB_OT_compare(bpy.types.Operator):
    """Compare each technique with Cycles random walk on this scene and write a report"""

    bl_idname = "sss_lab.compare"
    bl_label = "Compare with Cycles"
    bl_options = {"REGISTER"}

    directory: bpy.props.StringProperty(
        name="Report Folder",
        description="Folder for the report (metrics.json, report.html, images)",
        subtype="DIR_PATH",
        default="//sss_lab_report/",
        options={"PATH_SUPPORTS_BLEND_RELATIVE"},
    )
    reference_samples: bpy.props.IntProperty(
        name="Reference Samples",
        min=1,
        default=CompareSettings.reference_samples,
        description="Cycles samples of the random-walk reference",
    )
    pass_samples: bpy.props.IntProperty(
        name="Pass Samples",
        min=1,
        default=CompareSettings.pass_samples,
        description="Cycles samples of the passes the techniques run on",
    )

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        out_dir = bpy.path.abspath(self.directory)
        # An unsaved file has no folder for "//": abspath would quietly use the working directory.
        if not out_dir or (self.directory.startswith("//") and not bpy.data.filepath):
            self.report({"ERROR"}, "Save the .blend file first, or choose an absolute report folder")
            return {"CANCELLED"}
        settings = CompareSettings(reference_samples=self.reference_samples, pass_samples=self.pass_samples)
        wm = context.window_manager
        steps = iter(range(10_000))
        wm.progress_begin(0, 100)

        def log(line):
            print(line)
            wm.progress_update(min(next(steps), 100))

        try:
            data = compare(context.scene, out_dir, settings, log=log)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        best = [e for e in data["entries"] if e["name"] in data["pareto"] and e["kind"] == "technique"]
        for e in best:
            self.report(
                {"INFO"}, f"{e['name']}: rel. RMSE {e['metrics']['rel_rmse']:.4f}, {e['time_s']['total']:.2f} s"
            )
        level = {"INFO"} if data["complete"] else {"WARNING"}
        self.report(
            level,
            f"Report: {os.path.join(out_dir, 'report.html')}"
            + ("" if data["complete"] else " (incomplete: " + "; ".join(data["notes"]) + ")"),
        )
        return {"FINISHED"}


classes = (SSS_LAB_OT_compare,)
