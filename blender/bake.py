"""Bake thickness maps: inverted-normal ambient occlusion per mesh, with Cycles.

``bake_thickness(context, objects, settings)`` is the plain function (scripts call it); the
operator ``bpy.ops.sss_lab.bake_thickness`` (``operators/thickness.py``) wraps it, modal in the UI (one object per timer
step, Esc cancels between objects, Blender's progress API) and blocking headless.

How: a temporary material — Ambient Occlusion node (Inside, Only Local per setting) into an
Emission shader, inverted for the translucency convention (``core/scene/thickness.py`` explains the
values) — replaces the object's materials while Cycles bakes the Emit pass; then everything is
put back (``SceneState``): render engine, samples, film exposure, bake settings, materials,
visibility, selection and active object, also when a bake fails or the batch is cancelled.

With ``BakeSettings.source`` "ray" (attribute target) there is no Cycles bake: ``ray_thickness``
casts rays inwards along the normals around each vertex and the map holds the AO a slab of the
shortest distance found would bake (``core/scene/thickness.py`` ``SOURCES``).

What is baked is the mesh as Cycles renders it: modifiers applied with their render settings
(``as_rendered``: the viewport's switches and subdivision levels set to the render's while the
batch runs, and put back after).
Targets:

- ``attribute``: a float colour attribute (point domain) on the object's own mesh. Blender
  maps the evaluated mesh's corners back to the original vertices, so each original vertex gets
  the value baked where the modifiers put it; vertices that the modifiers delete get 0.
  Vertices that modifiers add have no place in the original mesh: when rendering, the
  modifiers carry the attribute to them as they carry any attribute (interpolated by
  subdivision, copied by solidify or mirror). No other mesh data changes; the attribute is
  written only when the bake succeeded.
- ``image``: an image over the active UV map of the evaluated mesh, saved (float32 OpenEXR or
  16-bit PNG, linear, Non-Color) atomically into the chosen folder, with a JSON file beside it.

A mesh used by several objects is baked once, with the first of them (transform, modifiers and
surroundings of that object); the others report that they share it. The settings and the
convention are stored with the result: ``mesh["sss_lab_thickness"][attribute name]`` or
``image["sss_lab_thickness"]`` (read them back with ``blender.stored.thickness_metadata``).

With ``link_materials`` the result is added to the object's materials: an Attribute or UV Map +
Image Texture node feeding a Shader AOV output named ``aov_name`` ("Thickness", the AOV the
render passes read), so the map can be used right away. Nodes SSS Lab adds carry names that
start with "SSS Lab Thickness" and are updated, not duplicated, by the next bake (the shader nodes
of the bake live in ``blender/bake_nodes.py``).

Undo: the operator registers an undo step (attributes, images, material nodes); the image files
written to disk stay.
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from typing import Any

import bpy
import numpy as np

from ..core.base import files
from ..core.base.errors import SSSLabError, describe_os_error, is_bad_input
from ..core.base.jsonfile import read_json
from ..core.base.progress import printable
from ..core.scene.thickness import (
    IMAGE_FORMATS,
    SOURCES,
    BakeSettings,
    auto_distance_su,
    slab_unoccluded_fraction,
    split_samples,
    to_convention,
)
from . import compat
from .bake_nodes import add_map_nodes, bake_material, result_image, use_material
from .describe import material_sss, world_corners
from .jobs import Job, Progress
from .state import SceneState
from .stored import META_KEY, thickness_metadata

_TMP_ATTRIBUTE = "SSSLab_thickness_bake"

STATUSES = ("baked", "shared", "skipped", "failed", "cancelled")


class BakeError(ValueError):
    """Nothing was baked: the input cannot be baked as asked (the message says why and what to do)."""


@dataclass
class BakeResult:
    """What happened to one object. ``seconds`` covers the bake, saving and material linking."""

    object: str
    status: str
    message: str = ""
    target: str = ""
    mesh: str = ""
    data: str = ""  # attribute or image name
    filepath: str = ""  # the image file, absolute
    distance_su: float = 0.0
    distance_auto: bool = False
    samples: int = 0  # AO rays per vertex or texel
    seconds: float = 0.0
    vertices: int = 0  # of the evaluated mesh
    warnings: list = field(default_factory=list)
    #: True when it failed because a file could not be written (a full or read-only disk): a
    #: failed write, not bad input (``core.base.errors.is_bad_input``).
    write_failed: bool = False

    def __str__(self) -> str:
        text = f"{printable(self.object)}: {self.message}"
        return text + "".join(f"; {w}" for w in self.warnings)

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class _Item:
    obj: Any  # a bpy Object
    mesh: Any  # its bpy Mesh
    distance_su: float
    distance_auto: bool
    vertices: int
    uv_map: str = ""
    sharers: list = field(default_factory=list)  # (object, warning or "")
    coarse: str = ""  # a warning when the mesh is too coarse for a per-vertex map


def _reason(exc: Exception) -> str:
    """Why an object failed, in one readable line: SSS Lab's own message, an operating-system
    error as ``describe_os_error`` says it, Blender's message; the repr only for anything else
    (a bug: its class helps)."""
    if isinstance(exc, SSSLabError):
        text = str(exc)
    elif isinstance(exc, OSError) and exc.strerror:
        text = describe_os_error(exc)
    elif isinstance(exc, RuntimeError):
        text = str(exc).removeprefix("Error: ")
    else:
        text = repr(exc)
    return " ".join(text.split()) or type(exc).__name__


def settings_from_scene(scene) -> BakeSettings:
    """The bake settings of the SSS Lab panel (``scene.sss_lab.bake``), or the defaults when
    the add-on's properties are not registered."""
    props = getattr(getattr(scene, "sss_lab", None), "bake", None)
    return props.to_settings() if props is not None else BakeSettings()


def _context_parts(context):
    if isinstance(context, bpy.types.Scene):
        if context != bpy.context.scene:
            raise BakeError(
                f"scene {context.name!r} is not the active scene ({bpy.context.scene.name!r}); Blender bakes the "
                "active scene: make it active first (window.scene = ...)"
            )
        context = bpy.context
    if context.scene is None or context.view_layer is None:
        raise BakeError("no active scene and view layer to bake in")
    return context, context.scene, context.view_layer


def _world_area(obj_eval) -> float:
    mesh = obj_eval.data
    mesh.calc_loop_triangles()
    n_tri = len(mesh.loop_triangles)
    if n_tri == 0:
        return 0.0
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    m = np.array(obj_eval.matrix_world, dtype=np.float64)
    world = co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T
    tris = np.empty(n_tri * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    a, b, c = (world[tris.reshape(-1, 3)[:, k]] for k in range(3))
    return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


def _describe_kind(obj) -> str:
    hint = " (convert it to a mesh first)" if obj.type in ("CURVE", "SURFACE", "META", "FONT", "CURVES") else ""
    return f"skipped: not a mesh ({obj.type}){hint}"


class ThicknessBake:
    """One batch: ``start()``, then ``step()`` until it returns False (one object per step), or
    ``cancel()``; ``finish()`` restores the scene (``cancel`` calls it; calling it twice is fine).

    Validation happens in the constructor: a BakeError lists every object that cannot be baked
    (nothing has changed then).
    """

    def __init__(
        self,
        context,
        objects: Iterable | None = None,
        settings: BakeSettings | None = None,
        *,
        log: Callable[[str], None] | None = print,
    ):
        self.context, self.scene, self.view_layer = _context_parts(context)
        self.settings = settings if settings is not None else settings_from_scene(self.scene)
        if not isinstance(self.settings, BakeSettings):
            raise TypeError(f"settings: expected a BakeSettings, got {type(self.settings).__name__}")
        self.log = log
        self._results: dict[str, BakeResult] = {}
        self._order: list[str] = []
        self._queue: list[_Item] = []
        self._state: SceneState | None = None
        self._material: Any = None  # the temporary bake material, while a batch runs
        self._material_images: dict[str, str] = {}
        self._image_folder = ""
        self._made_folders: list[str] = []  # the image folder and its parents ``start`` made, deepest first
        self._started = self._finished = False
        #: The result of the object the last ``step`` baked.
        self.last: BakeResult | None = None
        self._plan(self._resolve(objects))
        self.total = len(self._queue)
        self.done = 0

    # -- planning ---------------------------------------------------------------------------
    def _resolve(self, objects) -> list:
        if objects is None:
            objects = list(self.context.selected_objects or ())
        resolved, missing = [], []
        for item in objects:
            if isinstance(item, str):
                obj = self.scene.objects.get(item)
                if obj is None:
                    missing.append(item)
                    continue
                item = obj
            if item not in resolved:
                resolved.append(item)
        if missing:
            raise BakeError(f"no object named {', '.join(map(repr, missing))} in scene {self.scene.name!r}")
        if not resolved:
            raise BakeError(
                "nothing to bake: no objects selected (select mesh objects in the 3D Viewport, or name them: "
                "bpy.ops.sss_lab.bake_thickness(objects=[{'name': 'Cube'}]))"
            )
        return resolved

    def _plan(self, objects) -> None:
        # The meshes as Cycles renders them, for the plan only: the scene is as it was after it.
        with SceneState() as st:
            as_rendered(st, objects)
            self._plan_rendered(objects)

    def _plan_rendered(self, objects) -> None:
        s = self.settings
        depsgraph = self.context.evaluated_depsgraph_get()
        in_layer = set(self.view_layer.objects)
        errors: list[str] = []
        by_mesh: dict[Any, Any] = {}
        for obj in objects:
            self._order.append(obj.name)
            if obj.type != "MESH":
                self._results[obj.name] = BakeResult(obj.name, "skipped", _describe_kind(obj))
                continue
            mesh = obj.data
            if obj.library is not None or mesh.library is not None:
                lib = obj.library or mesh.library
                what = "object" if obj.library is not None else f"its mesh {mesh.name!r}"
                errors.append(
                    f"{obj.name!r}: {what} is linked from the library {lib.filepath!r} and cannot be changed; "
                    "make it local (Object > Relations > Make Local) or bake in the library file"
                )
                continue
            if not (obj.is_editable and mesh.is_editable):
                errors.append(f"{obj.name!r}: not editable (a library override); make it local first")
                continue
            if obj not in in_layer:
                errors.append(
                    f"{obj.name!r}: not in the view layer {self.view_layer.name!r} (its collection is excluded)"
                )
                continue
            if obj.mode != "OBJECT":
                errors.append(f"{obj.name!r}: in {obj.mode.replace('_', ' ').title()} mode; switch to Object Mode")
                continue
            if not obj.visible_get(view_layer=self.view_layer) and not (obj.hide_get() or obj.hide_viewport):
                errors.append(f"{obj.name!r}: hidden by its collection; show the collection in the Outliner")
                continue
            key = mesh.name_full
            if key in by_mesh:
                first = by_mesh[key]
                warning = ""
                if _bake_signature(obj) != _bake_signature(first.obj):
                    name = first.obj.name
                    warning = f"its modifiers or scale differ from {name!r}'s: the map is {name!r}'s"
                first.sharers.append((obj, warning))
                continue
            obj_eval = obj.evaluated_get(depsgraph)
            mesh_eval = obj_eval.data
            if _world_area(obj_eval) <= 0.0:
                self._results[obj.name] = BakeResult(
                    obj.name,
                    "skipped",
                    f"skipped: mesh {mesh.name!r} has no surface area (no faces, or only degenerate ones): "
                    "nothing to bake",
                    mesh=mesh.name,
                )
                continue
            uv_map = ""
            if s.target == "image":
                if mesh_eval.uv_layers.active is None:
                    errors.append(
                        f"{obj.name!r}: mesh {mesh.name!r} has no UV map, which the image target needs; add one "
                        "(UV > Smart UV Project) or bake to a colour attribute"
                    )
                    continue
                uv_map = mesh_eval.uv_layers.active.name
            else:
                existing = mesh.attributes.get(s.attribute_name)
                ours = thickness_metadata(mesh, s.attribute_name) is not None
                if existing is not None and not ours:
                    errors.append(
                        f"{obj.name!r}: mesh {mesh.name!r} already has an attribute {s.attribute_name!r} that SSS Lab "
                        "did not bake; choose another attribute name"
                    )
                    continue
            if s.distance_su > 0:
                distance, auto = float(s.distance_su), False
            else:
                distance, auto = auto_distance_su(world_corners(obj_eval)), True
            by_mesh[key] = _Item(obj, mesh, distance, auto, len(mesh_eval.vertices), uv_map)
            if s.target == "attribute" and s.source == "ao":
                by_mesh[key].coarse = coarse_warning(obj_eval, mesh.name, distance)
            self._queue.append(by_mesh[key])
        if s.target == "image" and self._queue:
            folder = s.image_folder
            if folder.startswith("//") and not bpy.data.filepath:
                errors.append(
                    f"image folder {folder!r} is relative to the .blend file, which is not saved yet; save it or "
                    "choose an absolute folder"
                )
            else:
                self._image_folder = os.path.abspath(bpy.path.abspath(folder))
                if os.path.exists(self._image_folder) and not os.path.isdir(self._image_folder):
                    errors.append(f"image folder {self._image_folder!r} exists and is not a folder")
                else:
                    errors += self._image_clashes()
        if errors:
            raise BakeError("cannot bake thickness:\n  - " + "\n  - ".join(errors))
        if not self._queue and all(r.status == "skipped" and not r.mesh for r in self._results.values()):
            kinds = ", ".join(f"{name!r} ({self.scene.objects[name].type})" for name in self._order)
            raise BakeError(f"nothing to bake: none of the objects is a mesh: {kinds}")

    # -- running ----------------------------------------------------------------------------
    @property
    def results(self) -> list[BakeResult]:
        """One result per object asked for, in the order asked; objects not reached yet are
        listed as cancelled once the batch is finished."""
        out = []
        for name in self._order:
            r = self._results.get(name)
            if r is None:
                r = BakeResult(name, "cancelled", "cancelled before it was baked")
            out.append(r)
        return out

    @property
    def remaining(self) -> int:
        return len(self._queue)

    def start(self) -> None:
        if self._started:
            return
        self._started = True
        s, scene = self.settings, self.scene
        st = self._state = SceneState()
        try:
            vl = self.view_layer
            selected = [o for o in vl.objects if o.select_get(view_layer=vl)]
            active = vl.objects.active

            def restore_selection():
                for o in vl.objects:
                    if o.select_get(view_layer=vl):
                        o.select_set(False, view_layer=vl)
                for o in selected:
                    o.select_set(True, view_layer=vl)
                vl.objects.active = active

            st.on_restore(restore_selection)
            as_rendered(st, [item.obj for item in self._queue])
            render_samples, node_samples = split_samples(s.samples)
            st.set(scene.render, "engine", "CYCLES")
            cycles = scene.cycles
            st.set(cycles, "samples", render_samples)
            st.set(cycles, "use_adaptive_sampling", False)
            st.set(cycles, "time_limit", 0.0)
            st.set(cycles, "film_exposure", 1.0)  # Cycles scales baked emission by it
            st.set(cycles, "bake_type", "EMIT")
            bake = scene.render.bake
            st.set(*compat.multires_bake_switch(scene), False)
            for attr, value in (
                ("target", "VERTEX_COLORS" if s.target == "attribute" else "IMAGE_TEXTURES"),
                ("use_selected_to_active", False),
                ("use_cage", False),
                ("use_clear", True),
                ("use_split_materials", False),
                ("save_mode", "INTERNAL"),
                ("margin", s.margin_px),
                ("margin_type", "ADJACENT_FACES"),
                ("view_from", "ABOVE_SURFACE"),
            ):
                st.set(bake, attr, value)
            self._material = bake_material(s, node_samples)
            material = self._material
            st.on_restore(lambda: bpy.data.materials.remove(material))
            if s.target == "image" and self._image_folder:  # empty when every object is skipped
                folder = self._image_folder
                while folder and not os.path.lexists(folder) and folder != os.path.dirname(folder):
                    self._made_folders.append(folder)
                    folder = os.path.dirname(folder)
                os.makedirs(self._image_folder, exist_ok=True)
        except BaseException:
            self.finish()
            raise

    def step(self) -> bool:
        """Bake the next object; returns whether objects remain."""
        if not self._started:
            self.start()
        if not self._queue:
            return False
        item = self._queue.pop(0)
        self.done += 1
        t0 = time.perf_counter()
        result = BakeResult(
            item.obj.name,
            "failed",
            target=self.settings.target,
            mesh=item.mesh.name,
            distance_su=item.distance_su,
            distance_auto=item.distance_auto,
            samples=self.settings.samples,
            vertices=item.vertices,
        )
        try:
            self._bake_item(item, result)
            result.status = "baked"
        except Exception as exc:  # one object failing does not stop the batch; the scene is restored
            result.message = f"failed: {_reason(exc)}"
            result.write_failed = isinstance(exc, OSError) and not is_bad_input(exc)
        result.seconds = time.perf_counter() - t0
        if result.status == "baked":
            result.message = self._describe(item, result)
            if item.coarse:
                result.warnings.append(item.coarse)
        self._results[item.obj.name] = result
        self.last = result
        for obj, warning in item.sharers:
            self._results[obj.name] = self._sharer_result(obj, warning, result)
        if self.log is not None:
            for name in [item.obj.name] + [o.name for o, _ in item.sharers]:
                self.log(f"[{self.done}/{self.total}] {self._results[name]}")
        return bool(self._queue)

    def cancel(self) -> None:
        """Stop before the next object; objects baked so far keep their maps."""
        self._queue.clear()
        self.finish()

    def finish(self) -> None:
        if self._finished:
            return
        self._finished = True
        self._queue.clear()
        if self._state is not None:
            self._state.restore()
        for folder in self._made_folders:  # those no image was saved in: nothing left of a failed bake
            try:
                os.rmdir(folder)
            except OSError:  # not empty (an image was saved), or gone
                break

    # -- one object -------------------------------------------------------------------------
    def _bake_item(self, item: _Item, result: BakeResult) -> None:
        s = self.settings
        obj, mesh, vl = item.obj, item.mesh, self.view_layer
        image = created = None
        if s.source == "ray":
            self._ray_attribute(item)
            stored = thickness_metadata(mesh) or {}
            stored[s.attribute_name] = self._meta(item)
            mesh[META_KEY] = stored
            result.data = s.attribute_name
            if s.link_materials:
                result.warnings.extend(self._link_materials(item, None))
            return
        try:
            with SceneState() as st:
                if obj.hide_get(view_layer=vl):
                    obj.hide_set(False, view_layer=vl)
                    st.on_restore(lambda: obj.hide_set(True, view_layer=vl))
                for attr in ("hide_viewport", "hide_render", "hide_select"):
                    if getattr(obj, attr):
                        st.set(obj, attr, False)
                for o in vl.objects:
                    if o.select_get(view_layer=vl):
                        o.select_set(False, view_layer=vl)
                obj.select_set(True, view_layer=vl)
                vl.objects.active = obj
                use_material(st, obj, self._material)
                nodes = self._material.node_tree.nodes
                nodes["AO"].inputs["Distance"].default_value = item.distance_su
                if s.target == "attribute":
                    self._bake_attribute(st, item)
                else:
                    image, created = result_image(mesh, s)
                    nodes["Image"].image = image
                    self._material.node_tree.nodes.active = nodes["Image"]
                    compat.run_bake(target="IMAGE_TEXTURES", margin=s.margin_px, uv_layer=item.uv_map)
            meta = self._meta(item)
            if s.target == "attribute":
                stored = thickness_metadata(mesh) or {}
                stored[s.attribute_name] = meta
                mesh[META_KEY] = stored
                result.data = s.attribute_name
            else:
                assert image is not None  # the image target made one above
                result.filepath = self._save_image(image, item, meta)
                result.data = image.name
        except BaseException:
            if created is not None:
                bpy.data.images.remove(created)
            elif image is not None and image.filepath_raw:  # a re-bake: back to the previous file
                image.source = "FILE"
                image.reload()
            raise
        if s.link_materials:
            result.warnings.extend(self._link_materials(item, image))

    def _bake_attribute(self, st: SceneState, item: _Item) -> None:
        name = self.settings.attribute_name
        mesh = item.mesh
        colors = mesh.color_attributes
        old_active, old_default = colors.active_color_name, colors.default_color_name
        old_attr = mesh.attributes.active.name if mesh.attributes.active is not None else ""

        def restore_names():
            # The baked attribute may take the name of an old one, so restore by name.
            colors.active_color_name = old_active if old_active in mesh.attributes else ""
            colors.default_color_name = old_default if old_default in mesh.attributes else ""
            if old_attr and old_attr in mesh.attributes:
                mesh.attributes.active = mesh.attributes[old_attr]

        st.on_restore(restore_names)
        if _TMP_ATTRIBUTE in mesh.attributes:
            mesh.attributes.remove(mesh.attributes[_TMP_ATTRIBUTE])
        colors.new(_TMP_ATTRIBUTE, "FLOAT_COLOR", "POINT")

        def drop_tmp():
            if _TMP_ATTRIBUTE in mesh.attributes:
                mesh.attributes.remove(mesh.attributes[_TMP_ATTRIBUTE])

        st.on_restore(drop_tmp)
        colors.active_color_name = _TMP_ATTRIBUTE
        compat.run_bake(target="VERTEX_COLORS")
        # Only now replace the previous result: a failed bake leaves it untouched.
        if name in mesh.attributes:
            mesh.attributes.remove(mesh.attributes[name])
        mesh.attributes[_TMP_ATTRIBUTE].name = name

    def _ray_attribute(self, item: _Item) -> None:
        """The "ray" source: ``ray_thickness`` per vertex, as the AO a slab of that thickness
        bakes, written like the Cycles bake's result (a point-domain float colour attribute that
        replaces the previous one only once computed)."""
        s = self.settings
        mesh = item.mesh
        depsgraph = self.context.evaluated_depsgraph_get()
        x = ray_thickness(item.obj, depsgraph, item.distance_su)
        value = to_convention(slab_unoccluded_fraction(x, item.distance_su), s.convention)
        rgba = np.ones((len(mesh.vertices), 4), np.float32)
        rgba[:, :3] = value[:, None]
        if _TMP_ATTRIBUTE in mesh.attributes:
            mesh.attributes.remove(mesh.attributes[_TMP_ATTRIBUTE])
        attr = mesh.color_attributes.new(_TMP_ATTRIBUTE, "FLOAT_COLOR", "POINT")
        attr.data.foreach_set("color", rgba.ravel())
        if s.attribute_name in mesh.attributes:
            mesh.attributes.remove(mesh.attributes[s.attribute_name])
        mesh.attributes[_TMP_ATTRIBUTE].name = s.attribute_name
        mesh.update()

    def _meta(self, item: _Item) -> dict:
        s = self.settings
        render_samples, node_samples = split_samples(s.samples)
        meta = {
            "convention": s.convention,
            "meaning": s.meaning,
            "source": (
                "Cycles Ambient Occlusion node, Inside" + (", Only Local" if s.only_local else "")
                if s.source == "ao"
                else SOURCES["ray"]
            ),
            "samples": s.samples,
            "render_samples": render_samples,
            "node_samples": node_samples,
            "distance_su": item.distance_su,
            "distance_auto": item.distance_auto,
            "only_local": s.only_local,
            "target": s.target,
            "object": item.obj.name,
            "mesh": item.mesh.name,
            "modifiers": [m.name for m in item.obj.modifiers if m.show_render],
            "blender": bpy.app.version_string,
        }
        if s.target == "image":
            meta.update(uv_map=item.uv_map, resolution_px=s.resolution_px, margin_px=s.margin_px)
        else:
            meta.update(attribute=s.attribute_name, domain="POINT")
        return meta

    def _image_file(self, item: _Item) -> str:
        """The file name of ``item``'s map in the image folder."""
        return bpy.path.clean_name(item.mesh.name) + "_thickness" + IMAGE_FORMATS[self.settings.image_format]

    def _image_clashes(self) -> list[str]:
        """Why the maps cannot be written (checked before anything is baked): two meshes whose names
        give the same file name, or an existing file that SSS Lab did not bake from the same mesh
        (its sidecar JSON says which mesh it was) while ``overwrite`` is off."""
        errors = []
        by_file: dict[str, list[str]] = {}
        for item in self._queue:
            by_file.setdefault(self._image_file(item), []).append(item.mesh.name)
        for filename, meshes in by_file.items():
            if len(meshes) > 1:
                names = ", ".join(printable(repr(m)) for m in meshes)
                errors.append(
                    f"meshes {names} would all be written to {filename!r} (their names differ only in characters a "
                    "file name cannot hold): rename all but one"
                )
                continue
            path = os.path.join(self._image_folder, filename)
            if self.settings.overwrite or not any(os.path.lexists(p) for p in (path, path + ".json")):
                continue
            try:
                ours = read_json(path + ".json", "the metadata of a baked image").get("mesh") == meshes[0]
            except (OSError, ValueError, AttributeError):
                ours = False
            if not ours or not os.path.isfile(path):
                errors.append(
                    f"{path!r} exists and SSS Lab did not bake it from mesh {printable(meshes[0])!r}; refusing to"
                    " overwrite it (choose another image folder; on the command line --overwrite allows it)"
                )
        return errors

    def _save_image(self, image, item: _Item, meta: dict) -> str:
        s = self.settings
        filename = self._image_file(item)
        path = os.path.join(self._image_folder, filename)
        sidecar = path + ".json"
        meta = dict(meta, file=filename, format=s.image_format, bit_depth=32 if s.image_format == "OPEN_EXR" else 16)
        previous = image.filepath_raw
        try:
            with files.temporary_beside(path) as tmp:
                try:
                    compat.save_float_image(image, tmp, s.image_format)
                except RuntimeError as exc:  # "Could not write image: Invalid argument" on a full disk
                    raise files.write_failure(path, exc) from None
                files.move_into_place(tmp, path)
            try:
                files.write_text(sidecar, json.dumps(meta, indent=2, sort_keys=True))
            except BaseException:
                # An image without its sidecar is not SSS Lab's to the next run (``_image_clashes``),
                # which would then refuse to replace it: nothing is left of this one.
                with contextlib.suppress(OSError):
                    os.remove(path)
                raise
        except BaseException:
            image.filepath_raw = previous
            raise
        image.filepath_raw = _stored_path(s.image_folder, filename, path)
        image[META_KEY] = meta
        return path

    def _link_materials(self, item: _Item, image) -> list[str]:
        """Add the map to the object's materials; returns warnings."""
        warnings, seen = [], set()
        materials = [slot.material for slot in item.obj.material_slots if slot.material is not None]
        if not materials:
            return ["no material to add the map to"]
        for mat in materials:
            if mat.name_full in seen:
                continue
            seen.add(mat.name_full)
            if mat.library is not None or not mat.is_editable:
                warnings.append(f"material {mat.name!r} is linked from a library: the map was not added to it")
                continue
            if image is not None:
                previous = self._material_images.get(mat.name_full)
                if previous is not None and previous != image.name:
                    warnings.append(
                        f"material {mat.name!r} is shared with a mesh baked to {previous!r}: "
                        f"it now shows {image.name!r}"
                    )
                self._material_images[mat.name_full] = image.name
            warning = add_map_nodes(mat, self.settings, image, item.uv_map)
            if warning:
                warnings.append(warning)
        return warnings

    def _describe(self, item: _Item, result: BakeResult) -> str:
        s = self.settings
        how = "auto: a quarter of the bounding-box diagonal" if item.distance_auto else "set"
        occluders = "only local" if s.only_local else "all objects occlude"
        if s.target == "attribute":
            what = f"attribute {s.attribute_name!r} on mesh {item.mesh.name!r} ({item.vertices} vertices evaluated)"
        else:
            size = f"{s.resolution_px}x{s.resolution_px}"
            what = f"image {result.data!r} {size} over UV map {item.uv_map!r} -> {result.filepath}"
        rays = f"{s.samples} rays" if s.source == "ao" else "rays along the inward normals"
        if s.source == "ray":
            occluders = "the object itself"
        return (
            f"baked {s.convention} {what}; {rays}, distance {item.distance_su:.4g} ({how}), {occluders}; "
            f"{result.seconds:.2f} s"
        )

    def _sharer_result(self, obj, warning: str, source: BakeResult) -> BakeResult:
        r = BakeResult(
            obj.name,
            source.status,
            target=source.target,
            mesh=source.mesh,
            data=source.data,
            filepath=source.filepath,
            distance_su=source.distance_su,
            distance_auto=source.distance_auto,
            samples=source.samples,
        )
        if source.status == "baked":
            r.status = "shared"
            r.message = f"shares mesh {source.mesh!r} with {source.object!r}, baked once ({source.data!r})"
            if self.settings.link_materials:
                image = bpy.data.images.get(source.data) if source.target == "image" else None
                uv = (thickness_metadata(image) or {}).get("uv_map", "") if image is not None else ""
                r.warnings.extend(self._link_materials(_Item(obj, obj.data, 0.0, False, 0, uv), image))
        else:
            r.message = f"{source.status}: shares mesh {source.mesh!r} with {source.object!r}"
        if warning:
            r.warnings.append(warning)
        return r


def carries_subsurface(obj) -> bool:
    """Whether a material of ``obj`` scatters, read as the scene description reads it
    (``describe.material_sss``: a Principled BSDF inside a group or behind a Mix Shader, a
    linked Subsurface Weight)."""
    for slot in obj.material_slots:
        sss = material_sss(slot.material, 1)
        if sss is not None and sss.scatters:
            return True
    return False


def subsurface_meshes(scene, view_layer=None) -> list:
    """The local mesh objects of ``scene`` that render, are in the view layer and carry a
    subsurface material: what ``bake-thickness`` bakes when no object is named."""
    layer = set((view_layer or bpy.context.view_layer).objects)
    return [
        o
        for o in scene.objects
        if o.type == "MESH"
        and not o.hide_render
        and o.library is None
        and o.data.library is None
        and o in layer
        and carries_subsurface(o)
    ]


def ray_thickness(obj, depsgraph, distance_su: float) -> np.ndarray:
    """Per vertex of ``obj``'s own mesh: the distance (scene units, at most ``distance_su``) from
    the surface as rendered (modifiers applied) to its far side, along the inward normal.

    World space: the evaluated mesh in a BVH tree. Each vertex is placed at the nearest point of
    that surface; a ray goes inwards along the normal of each face around the vertex and along the
    nearest face's normal, and the shortest hit counts (at a box's corner, its thinnest
    dimension; on a smooth surface the normals agree). No hit within the distance: the distance."""
    from mathutils import Matrix, Vector
    from mathutils.bvhtree import BVHTree

    ev = obj.evaluated_get(depsgraph)
    me_ev = ev.data
    m = Matrix(obj.matrix_world)
    normal_m = m.to_3x3().inverted_safe().transposed()
    verts = [m @ v.co for v in me_ev.vertices]
    tree = BVHTree.FromPolygons(verts, [tuple(p.vertices) for p in me_ev.polygons])
    mesh = obj.data
    around: list[list] = [[] for _ in mesh.vertices]
    for poly in mesh.polygons:
        n = (normal_m @ poly.normal).normalized()
        for i in poly.vertices:
            around[i].append(n)
    out = np.full(len(mesh.vertices), float(distance_su), np.float64)
    for i, v in enumerate(mesh.vertices):
        location, normal, _index, _dist = tree.find_nearest(m @ v.co)
        if location is None:
            continue
        # Rays start a hair inside the surface as rendered, along the mean of the normals of the
        # faces that meet at the start (a box's corner: its three faces): a ray from the corner
        # itself along one face's normal would run in the planes of the faces beside it, where
        # float rounding makes it cross them or miss the far corner once the box is turned. Only
        # rays that head inwards there count (a sheet given thickness by a modifier: its own
        # normals point out of one side of the shell). The start's depth along each ray is added
        # back (exact on a slab). Tolerances: twice float32's rounding of a coordinate this far
        # from the world's origin (and a millionth of D), far below a thickness a bake reads; the
        # start eight of them inside (docs/references.md §14).
        tol = 2.4e-7 * float(location.length) + 1e-6 * float(distance_su)
        met = [Vector(n) for _loc, n, _j, _d in tree.find_nearest_range(location, tol)] or [Vector(normal)]
        inward = -sum(met, Vector((0.0, 0.0, 0.0)))
        if inward.length == 0:
            inward = -Vector(normal)
        inward.normalize()
        nudge = 8.0 * tol
        origin = location + inward * nudge
        best = float(distance_su)
        for n in [*around[i], Vector(normal)]:
            if n.length == 0:
                continue
            direction = -n.normalized()
            ahead = float(direction.dot(inward))
            if ahead <= 0.0:
                continue
            best = min(best, _far_side(tree, origin, direction, best, tol) + nudge * ahead)
        out[i] = min(max(best, 0.0), float(distance_su))
    return out


def _far_side(tree, origin, direction, distance: float, tol: float) -> float:
    """The distance from ``origin`` along ``direction`` to the first face of ``tree`` that the ray
    crosses rather than runs along (a face whose plane passes within ``tol`` of ``origin`` is run
    along), or ``distance`` when there is none that near."""
    travelled = 0.0
    start = origin
    for _ in range(16):
        left = distance - travelled
        if left <= 0:
            break
        hit, hit_normal, _j, t = tree.ray_cast(start, direction, left)
        if hit is None or t is None:
            break
        if abs(float(hit_normal.dot(origin - hit))) > tol:
            return travelled + float(t)
        travelled += float(t) + tol
        start = hit + direction * tol
    return distance


def coarse_warning(obj_eval, mesh_name: str, distance_su: float) -> str:
    """A warning when a per-vertex map cannot hold the mesh's thickness, else "".

    A vertex attribute has one value per vertex, interpolated across each face. When an edge is
    longer than the bake distance D, the middle of a face lies farther than D from every vertex,
    and its thickness there (a slab's, read at the centre of its face) is whatever the corners,
    which see open space around them, measured: an 8-vertex box read as a slab is off by up to
    0.5 at its centre (docs/references.md §9). The remedy: more vertices, or an image target.
    """
    mesh = obj_eval.data
    n = len(mesh.vertices)
    if n == 0 or len(mesh.edges) == 0:
        return ""
    co = np.empty(n * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    m = np.array(obj_eval.matrix_world, dtype=np.float64)
    world = co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    edges = np.empty(len(mesh.edges) * 2, np.int64)
    mesh.edges.foreach_get("vertices", edges)
    pairs = edges.reshape(-1, 2)
    longest = float(np.linalg.norm(world[pairs[:, 0]] - world[pairs[:, 1]], axis=1).max())
    if longest <= distance_su:
        return ""
    return (
        f"mesh {mesh_name!r} is too coarse for a per-vertex thickness map: its longest edge ({longest:.3g}) is"
        f" longer than the bake distance ({distance_su:.3g}), so the thickness inside its faces is interpolated"
        " from corners that see open space; subdivide the mesh (Edit Mode > Subdivide, or an applied Simple"
        " Subdivision modifier) or bake to an image (target 'image', needs a UV map)"
    )


#: Modifiers whose viewport and render settings differ beyond their switches: (viewport, render).
RENDER_LEVELS = {"SUBSURF": ("levels", "render_levels"), "MULTIRES": ("levels", "render_levels")}


def as_rendered(st: SceneState, objects) -> None:
    """Evaluate ``objects``' modifiers as Cycles renders them, until ``st`` is restored: each
    modifier shown in the viewport as it is in the render, and a Subdivision Surface's or
    Multiresolution's viewport level set to its render level. The depsgraph Python reads is the
    viewport's, while the bake and the render evaluate render settings: a cage with 0 viewport and
    3 render levels would otherwise be baked from its cage vertices. (A geometry node tree that
    asks whether it is evaluated for the viewport still answers yes.)"""
    for obj in objects:
        if getattr(obj, "library", None) is not None or not getattr(obj, "is_editable", True):
            continue  # cannot be changed, and is refused with its reason before anything is baked
        for m in getattr(obj, "modifiers", ()):
            if m.show_viewport != m.show_render:
                st.set(m, "show_viewport", m.show_render)
            levels = RENDER_LEVELS.get(m.type)
            if levels is not None and getattr(m, levels[0]) != getattr(m, levels[1]):
                st.set(m, levels[0], getattr(m, levels[1]))


def _bake_signature(obj) -> tuple:
    scale = tuple(round(v, 6) for v in obj.matrix_world.to_scale())
    return scale, tuple((m.type, m.show_render) for m in obj.modifiers)


def _stored_path(folder: str, filename: str, absolute: str) -> str:
    """Keep the folder as the user gave it (``//`` relative paths stay relative)."""
    return folder.rstrip("/\\") + "/" + filename if folder.startswith("//") else absolute


def bake_job(batch: ThicknessBake) -> Job:
    """``batch`` as a job generator (``blender/jobs.py``): one object per step; returns its
    results. Closed between two objects (Esc), the batch is cancelled: the objects baked so far
    keep their maps, the others are reported cancelled, and the scene is restored."""
    yield Progress(0, batch.total, "object 1")
    try:
        batch.start()
        while batch.remaining:
            batch.step()
            if batch.remaining:
                yield Progress(batch.done, batch.total, f"object {batch.done + 1}")
    except GeneratorExit:
        batch.cancel()
        raise
    finally:
        batch.finish()
    return batch.results


def bake_thickness(
    context=None,
    objects: Iterable | None = None,
    settings: BakeSettings | None = None,
    *,
    cancel: Callable[[], bool] | None = None,
    progress: Callable[[int, int, BakeResult], None] | None = None,
    log: Callable[[str], None] | None = print,
) -> list[BakeResult]:
    """Bake a thickness map for each mesh of ``objects``; one BakeResult per object.

    ``context``: a bpy Context (``bpy.context`` when None) or the active Scene. ``objects``:
    objects or names; None = the selected objects. ``settings``: BakeSettings; None = the SSS
    Lab panel's. ``cancel()`` is asked before each object: True stops the batch (objects baked
    so far keep their maps, the rest are reported as cancelled). ``progress(done, total,
    result)`` is called after each object; ``log`` gets one line per object (stdout by
    default). Raises BakeError (a ValueError) before changing anything when the input cannot be
    baked (nothing selected, no mesh, linked library data, no UV map for the image target...).
    The scene is restored whatever happens.
    """
    job = ThicknessBake(context if context is not None else bpy.context, objects, settings, log=log)
    try:
        job.start()
        while job.remaining:
            if cancel is not None and cancel():
                job.cancel()
                if log is not None:
                    log(f"cancelled after {job.done} of {job.total} bakes")
                break
            job.step()
            if progress is not None and job.last is not None:  # (a step always leaves a result)
                progress(job.done, job.total, job.last)
    finally:
        job.finish()
    return job.results
