"""Scene description: the plain data that travels with the render passes.

The passes alone do not say where the camera is, which lights shine, or which material
scatters how far. This module holds that as frozen dataclasses that round-trip through JSON,
so that the NumPy passes run on any machine with Python and NumPy (a render-farm node without
Blender included). ``blender/describe.py`` fills it from a Blender scene; ``core``
reads it.

Conventions: lengths in scene units, colours linear, matrices row-major 4x4
object-to-world as Blender's ``matrix_world`` (a camera looks down its local -Z, a sun or spot
light shines down its local -Z).
"""

from __future__ import annotations

import json
import math
from dataclasses import MISSING, asdict, dataclass, field, fields

import numpy as np

from ..base import arrays
from ..base.jsonfile import parse_json
from .fit_values import check_fit
from .passes import INPUT_AOVS, PASSES, SHORT_NAMES

#: Version of the JSON layout; bump on any incompatible change.
SCENE_DESCRIPTION_VERSION = 1

CAMERA_TYPES = ("PERSP", "ORTHO")
SENSOR_FITS = ("AUTO", "HORIZONTAL", "VERTICAL")
LIGHT_TYPES = ("SUN", "POINT", "SPOT", "AREA")
#: Blender 5.2's Principled BSDF subsurface methods (docs/references.md §2).
SUBSURFACE_METHODS = ("BURLEY", "RANDOM_WALK", "RANDOM_WALK_SKIN", "RANDOM_WALK_LEGACY")

_IDENTITY = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0)


def _matrix(values, what: str) -> np.ndarray:
    try:
        m = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        m = np.zeros(0)
    if m.shape == (16,):
        m = m.reshape(4, 4)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ValueError(f"{what}: expected 16 finite numbers (a row-major 4x4 matrix), got {values!r}")
    return m


def _invertible(m: np.ndarray, what: str) -> None:
    """The 3x3 part of an object-to-world matrix must keep three independent axes: a camera or a
    light whose scale is 0 along some axis has no defined view or light direction."""
    sv = np.linalg.svd(m[:3, :3], compute_uv=False)
    if not (sv[0] > 0 and sv[-1] > 1e-9 * sv[0]):
        raise ValueError(
            f"{what}: the matrix is degenerate (its 3x3 part has rank < 3, singular values "
            f"{np.round(sv, 6).tolist()}); "
            "expected an object-to-world matrix with non-zero scale on every axis"
        )


def _choice(value: str, allowed: tuple[str, ...], what: str) -> None:
    if value not in allowed:
        raise ValueError(f"{what}: {value!r} is not one of {', '.join(allowed)}")


def _positive(value: float, what: str) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{what}: expected a finite number > 0, got {value!r}")


def _rgb(values, what: str) -> tuple[float, float, float]:
    try:
        t = tuple(float(v) for v in values)
    except TypeError:
        raise ValueError(f"{what}: expected three numbers (R, G, B), got {values!r}") from None
    if len(t) != 3 or not all(math.isfinite(v) for v in t):
        raise ValueError(f"{what}: expected three finite numbers (R, G, B), got {values!r}")
    return t


@dataclass(frozen=True)
class Camera:
    """A Blender camera as far as the passes need it.

    ``width_px``/``height_px`` are the rendered resolution (after the percentage scale).
    Sensor fit follows Blender: with ``AUTO`` the sensor width (and the orthographic scale)
    spans the larger image dimension.
    """

    type: str = "PERSP"
    width_px: int = 1920
    height_px: int = 1080
    lens_mm: float = 50.0
    sensor_width_mm: float = 36.0
    sensor_height_mm: float = 24.0
    sensor_fit: str = "AUTO"
    ortho_scale: float = 6.0
    clip_start: float = 0.1
    clip_end: float = 1000.0
    shift_x: float = 0.0
    shift_y: float = 0.0
    matrix_world: tuple = _IDENTITY

    def __post_init__(self):
        _choice(self.type, CAMERA_TYPES, "camera type")
        _choice(self.sensor_fit, SENSOR_FITS, "camera sensor_fit")
        for name in ("width_px", "height_px"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ValueError(f"camera {name}: expected an integer >= 1, got {v!r}")
        for name in ("lens_mm", "sensor_width_mm", "sensor_height_mm", "ortho_scale", "clip_start", "clip_end"):
            _positive(getattr(self, name), f"camera {name}")
        m = _matrix(self.matrix_world, "camera matrix_world")
        _invertible(m, "camera matrix_world")
        object.__setattr__(self, "matrix_world", tuple(m.ravel()))

    def _fit_is_horizontal(self) -> bool:
        if self.sensor_fit == "AUTO":
            return self.width_px >= self.height_px
        return self.sensor_fit == "HORIZONTAL"

    def _fit_extent(self) -> tuple[float, int]:
        """(sensor size in mm along the fitted axis, pixels along that axis)."""
        if self.sensor_fit == "AUTO":
            return self.sensor_width_mm, max(self.width_px, self.height_px)
        if self.sensor_fit == "HORIZONTAL":
            return self.sensor_width_mm, self.width_px
        return self.sensor_height_mm, self.height_px

    @property
    def focal_px(self) -> float:
        """Perspective focal length in pixels: pixels per scene unit at view depth 1."""
        sensor_mm, pixels = self._fit_extent()
        return self.lens_mm / sensor_mm * pixels

    def principal_point(self, width: int, height: int) -> tuple[float, float]:
        """Where the camera's axis meets an image of ``width`` x ``height`` pixels (pixel
        coordinates, x right, y down): the image's centre, moved by the lens shift (in units of
        the larger side) for a perspective camera."""
        if self.type == "ORTHO":
            return width / 2, height / 2
        side = max(width, height)
        return width / 2 - self.shift_x * side, height / 2 + self.shift_y * side

    @property
    def ortho_px_per_unit(self) -> float:
        """Orthographic pixels per scene unit (constant over the image)."""
        _, pixels = self._fit_extent()
        return pixels / self.ortho_scale

    @property
    def position(self) -> np.ndarray:
        return _matrix(self.matrix_world, "camera matrix_world")[:3, 3].copy()

    @property
    def forward(self) -> np.ndarray:
        """Unit view direction in world space (the camera's local -Z)."""
        m = _matrix(self.matrix_world, "camera matrix_world")
        f = -m[:3, 2]
        return f / max(np.linalg.norm(f), 1e-30)

    def pixels_per_unit(self, depth: np.ndarray) -> np.ndarray:
        """Screen footprint: pixels per scene unit at each pixel, from planar view depth.

        ``depth`` is (H, W) planar view z as Blender's Depth pass writes it (1e10 for
        background). Perspective: focal_px / z (docs/references.md §1, "Screen footprint").
        Orthographic: constant. Returns float32 (H, W); 0 where depth is not finite or <= 0.
        """
        z = np.asarray(depth, dtype=np.float32)
        if self.type == "ORTHO":
            out: np.ndarray = np.full(z.shape, self.ortho_px_per_unit, dtype=np.float32)
            out[~np.isfinite(z)] = 0.0
            return out
        with np.errstate(divide="ignore", invalid="ignore"):
            out = np.float32(self.focal_px) / z
        out[~np.isfinite(out) | (z <= 0)] = 0.0
        return out.astype(np.float32, copy=False)

    def view_vectors(self, position: np.ndarray) -> np.ndarray:
        """Unit vectors from each surface point toward the viewer, float32 (H, W, 3).

        ``position`` is the world-space Position pass (H, W, 3). Orthographic cameras have the
        same vector everywhere (minus the view direction).
        """
        p = np.asarray(position, dtype=np.float32)
        if p.ndim != 3 or p.shape[2] != 3:
            raise ValueError(f"position: expected shape (H, W, 3), got {p.shape}")
        if self.type == "ORTHO":
            return np.broadcast_to((-self.forward).astype(np.float32), p.shape).copy()
        v = self.position.astype(np.float32) - p
        n = arrays.vector_length(v)
        return (v / np.maximum(n, np.float32(1e-20))).astype(np.float32, copy=False)


@dataclass(frozen=True)
class Light:
    """A Blender light. ``energy`` is Blender's Power (W) for point, spot and area lights and
    Strength (W/m^2, irradiance) for a sun. ``radius`` is the light's Radius (point, spot),
    ``size``/``size_y`` the area light's extent, ``angle`` the sun's angular diameter (rad).
    ``spot_size`` is the full cone angle (rad) and ``spot_blend`` Blender's Blend (0..1).
    """

    type: str
    name: str = ""
    color: tuple = (1.0, 1.0, 1.0)
    energy: float = 10.0
    matrix_world: tuple = _IDENTITY
    radius: float = 0.0
    size: float = 0.0
    size_y: float = 0.0
    angle: float = 0.0
    spot_size: float = math.radians(45.0)
    spot_blend: float = 0.15

    def __post_init__(self):
        _choice(self.type, LIGHT_TYPES, f"light {self.name!r} type")
        object.__setattr__(self, "color", _rgb(self.color, f"light {self.name!r} color"))
        if not (math.isfinite(self.energy) and self.energy >= 0):
            raise ValueError(f"light {self.name!r} energy: expected a finite number >= 0, got {self.energy!r}")
        if not (0 < self.spot_size <= math.pi + 1e-6):
            raise ValueError(f"light {self.name!r} spot_size: expected 0 < angle <= pi rad, got {self.spot_size!r}")
        if not (0 <= self.spot_blend <= 1):
            raise ValueError(f"light {self.name!r} spot_blend: expected 0..1, got {self.spot_blend!r}")
        for name in ("radius", "size", "size_y", "angle"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"light {self.name!r} {name}: expected a finite number >= 0, got {v!r}")
        m = _matrix(self.matrix_world, f"light {self.name!r} matrix_world")
        _invertible(m, f"light {self.name!r} matrix_world")
        object.__setattr__(self, "matrix_world", tuple(m.ravel()))

    @property
    def position(self) -> np.ndarray:
        return _matrix(self.matrix_world, "light matrix_world")[:3, 3].copy()

    @property
    def direction(self) -> np.ndarray:
        """Unit direction the light shines in (its local -Z), world space."""
        m = _matrix(self.matrix_world, "light matrix_world")
        d = -m[:3, 2]
        return d / max(np.linalg.norm(d), 1e-30)


@dataclass(frozen=True)
class MaterialSSS:
    """A material's subsurface inputs as the Principled BSDF holds them (docs/references.md §2).

    ``index`` is the material's Pass Index, the value of the Material Index pass on its pixels.
    """

    index: int
    name: str = ""
    method: str = "RANDOM_WALK"
    base_color: tuple = (0.8, 0.8, 0.8)
    subsurface_weight: float = 1.0
    subsurface_radius: tuple = (1.0, 0.2, 0.1)
    subsurface_scale: float = 0.005
    subsurface_ior: float = 1.4
    subsurface_anisotropy: float = 0.0
    #: The thickness bake's maximum distance D (scene units) of the material's objects, 0 when
    #: unknown: with it a translucency value tau reads back as a slab thickness D sqrt(1 - tau).
    thickness_distance: float = 0.0
    #: Parameters fitted against Cycles per technique (``core/study/fit.py``): technique name ->
    #: {"gain": (R, G, B), "d_scale": k, ...}; empty when the material was never fitted. Not
    #: hashed (a dict), compared like the other fields.
    fit: dict = field(default_factory=dict, hash=False)
    #: What the scene reader says about the material, one line each: where it found the Principled
    #: BSDF when not at the top of the tree, and each input it could not read as Cycles renders it
    #: (linked to a texture, read at its socket's value instead). Apply says them again.
    notes: tuple = ()
    #: The inputs linked to something read per pixel from the render (keys of
    #: ``core.scene.passes.INPUT_AOVS``: "base_color", "subsurface_radius", ...): the passes file
    #: holds a shader AOV for each, and ``core.scene.inputs`` reads it back. Empty when every
    #: input is typed in or a constant (the usual case, which costs nothing).
    per_pixel: tuple = ()
    #: True once ``core.scene.inputs.measure`` replaced the ``per_pixel`` inputs by their medians
    #: over the material's pixels.
    measured: bool = False

    def __post_init__(self):
        if not isinstance(self.index, int) or isinstance(self.index, bool) or self.index < 1:
            raise ValueError(
                f"material {self.name!r} index: expected a pass index >= 1 (0 is the background), got {self.index!r}"
            )
        _choice(self.method, SUBSURFACE_METHODS, f"material {self.name!r} subsurface method")
        object.__setattr__(self, "base_color", _rgb(self.base_color, f"material {self.name!r} base_color"))
        radius = _rgb(self.subsurface_radius, f"material {self.name!r} subsurface_radius")
        if min(radius) < 0:
            raise ValueError(f"material {self.name!r} subsurface_radius: expected values >= 0, got {radius!r}")
        object.__setattr__(self, "subsurface_radius", radius)
        for name in ("subsurface_weight", "subsurface_scale", "thickness_distance"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"material {self.name!r} {name}: expected a finite number >= 0, got {v!r}")
        if self.subsurface_weight > 1:  # Cycles' Subsurface Weight is a mix factor (0..1)
            raise ValueError(
                f"material {self.name!r} subsurface_weight: expected a number in 0..1, got {self.subsurface_weight!r}"
            )
        object.__setattr__(self, "fit", check_fit(self.fit, f"material {self.name!r}"))
        if isinstance(self.notes, str) or not all(isinstance(n, str) for n in self.notes):
            raise ValueError(f"material {self.name!r} notes: expected a list of strings, got {self.notes!r}")
        object.__setattr__(self, "notes", tuple(self.notes))
        if isinstance(self.per_pixel, str) or not all(isinstance(k, str) and k in INPUT_AOVS for k in self.per_pixel):
            raise ValueError(
                f"material {self.name!r} per_pixel: expected a list of some of {', '.join(INPUT_AOVS)}, "
                f"got {self.per_pixel!r}"
            )
        object.__setattr__(self, "per_pixel", tuple(self.per_pixel))
        if not (math.isfinite(self.subsurface_ior) and self.subsurface_ior > 0):
            raise ValueError(
                f"material {self.name!r} subsurface_ior: expected a finite number > 0, got {self.subsurface_ior!r}"
            )
        if not (math.isfinite(self.subsurface_anisotropy) and -1 <= self.subsurface_anisotropy <= 1):
            raise ValueError(
                f"material {self.name!r} subsurface_anisotropy: expected a number in -1..1, "
                f"got {self.subsurface_anisotropy!r}"
            )

    @property
    def scatters(self) -> bool:
        """True when the material has any subsurface scattering to model."""
        return self.subsurface_weight > 0 and self.subsurface_scale > 0 and max(self.subsurface_radius) > 0

    @property
    def radius(self) -> tuple[float, float, float]:
        """Subsurface Radius x Subsurface Scale, per channel, in scene units."""
        return tuple(r * self.subsurface_scale for r in self.subsurface_radius)


@dataclass(frozen=True)
class SceneDescription:
    """Everything besides the pixels that a technique needs for one frame."""

    camera: Camera
    lights: tuple = ()
    materials: tuple = ()
    frame: int = 1
    #: Name of the thickness AOV in the passes, and its convention ("translucency": 1 = thin).
    thickness_aov: str = "Thickness"
    thickness_convention: str = "translucency"
    #: Free-form provenance (Blender version, file, samples); never read by the techniques.
    meta: dict = field(default_factory=dict)
    version: int = SCENE_DESCRIPTION_VERSION

    def __post_init__(self):
        if self.thickness_aov in PASSES or self.thickness_aov in SHORT_NAMES:
            raise ValueError(
                f"thickness_aov: {self.thickness_aov!r} is a render pass of Blender's, not a thickness map;"
                " expected the name of the shader AOV the bake feeds (default Thickness)"
            )
        if self.thickness_convention not in ("translucency", "thickness"):
            raise ValueError(
                f"thickness_convention: {self.thickness_convention!r} is not one of translucency, thickness"
            )
        indices = [m.index for m in self.materials]
        dupes = sorted({i for i in indices if indices.count(i) > 1})
        if dupes:
            raise ValueError(f"materials: pass index used twice: {dupes}")

    def material(self, index: int) -> MaterialSSS:
        for m in self.materials:
            if m.index == index:
                return m
        raise KeyError(f"no material with pass index {index}; known: {[m.index for m in self.materials]}")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["camera"]["matrix_world"] = list(self.camera.matrix_world)
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, sort_keys=True)

    @classmethod
    def from_dict(cls, data: dict) -> SceneDescription:
        """A scene description from JSON data, checked against the dataclasses' fields first:
        unknown keys, wrong types and non-finite numbers are named with their place
        (``materials[0].subsurface_radius``); ranges are checked by the classes themselves."""
        if not isinstance(data, dict):
            raise ValueError(f"scene description: expected a JSON object, got {type(data).__name__}")
        version = data.get("version")
        if version != SCENE_DESCRIPTION_VERSION:
            raise ValueError(
                f"scene description version: expected {SCENE_DESCRIPTION_VERSION}, got {version!r}"
                " (written by another SSS Lab version)"
            )
        _check_fields(cls, data, "", required=("camera", "version"))
        camera = _check_fields(Camera, data["camera"], "camera")
        lights = data.get("lights", [])
        materials = data.get("materials", [])
        for key, items in (("lights", lights), ("materials", materials)):
            if not isinstance(items, (list, tuple)):
                raise ValueError(f"{key}: expected a JSON list, got {_kind(items)}")
        try:
            cam = Camera(**camera)
            lights = tuple(
                Light(**_check_fields(Light, item, f"lights[{i}]", required=("type",))) for i, item in enumerate(lights)
            )
            materials = tuple(
                MaterialSSS(**_check_fields(MaterialSSS, item, f"materials[{i}]", required=("index",)))
                for i, item in enumerate(materials)
            )
        except TypeError as exc:  # a value of the right JSON type the class still cannot take
            raise ValueError(f"scene description: malformed entry ({exc})") from None
        rest = {k: v for k, v in data.items() if k not in ("camera", "lights", "materials", "version")}
        return cls(camera=cam, lights=lights, materials=materials, **rest)

    @classmethod
    def from_json(cls, text: str) -> SceneDescription:
        data = parse_json(text, "scene description", "a scene description", parse_constant=_reject_constant)
        return cls.from_dict(data)


def _reject_constant(name: str):
    raise ValueError(f"scene description: {name} is not a number JSON allows; expected a finite number")


def _kind(value) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "true/false", type(None): "null"}.get(
        type(value), f"the {type(value).__name__} {value!r}"
    )


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _field_kind(cls, f) -> str:
    """What JSON value a dataclass field takes, from its default (or its name when it has none)."""
    explicit = {"camera": "object", "type": "str", "index": "int"}
    if f.name in explicit:
        return explicit[f.name]
    default = f.default_factory() if f.default_factory is not MISSING else f.default
    if isinstance(default, bool):
        return "bool"
    if isinstance(default, int):
        return "int"
    if isinstance(default, float):
        return "number"
    if isinstance(default, str):
        return "str"
    if isinstance(default, dict):
        return "object"
    if isinstance(default, tuple) and len(default) == 16:
        return "matrix"
    if isinstance(default, tuple) and len(default) == 3:
        return "rgb"
    return "any"


#: The largest float32: the passes are float32, and a number beyond it becomes Inf in them.
FLOAT32_MAX = float(np.finfo(np.float32).max)

_EXPECTED = {
    "int": "an integer (32-bit: |n| < 2**31)",
    "number": "a finite number within float32's range (|x| <= 3.4e38)",
    "str": "a string",
    "object": "a JSON object",
    "matrix": "a list of 16 finite numbers (a row-major 4x4 matrix, |x| <= 3.4e38)",
    "rgb": "a list of three finite numbers (R, G, B, |x| <= 3.4e38)",
    "bool": "true or false",
}


def _type_ok(kind: str, v) -> bool:
    if kind == "int":
        return isinstance(v, (int, np.integer)) and not isinstance(v, bool) and abs(int(v)) < 2**31
    if kind == "number":
        return _is_number(v) and math.isfinite(v) and abs(v) <= FLOAT32_MAX
    if kind == "str":
        return isinstance(v, str)
    if kind == "object":
        return isinstance(v, dict)
    if kind == "bool":
        return isinstance(v, bool)
    if kind in ("matrix", "rgb"):
        n = 16 if kind == "matrix" else 3
        return (
            isinstance(v, (list, tuple))
            and len(v) == n
            and all(_is_number(x) and math.isfinite(x) and abs(x) <= FLOAT32_MAX for x in v)
        )
    return True


def _check_fields(cls, data, where: str, required: tuple[str, ...] = ()) -> dict:
    """``data`` if it is a JSON object whose keys are ``cls``'s fields with values of their types."""
    label = where or "scene description"
    if not isinstance(data, dict):
        raise ValueError(f"{label}: expected a JSON object, got {_kind(data)}")
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(k for k in data if k not in known)
    if unknown:
        raise ValueError(
            f"{label}: unknown key(s) {', '.join(map(repr, unknown))}; expected some of {', '.join(sorted(known))}"
        )
    missing = [k for k in required if k not in data]
    if missing:
        raise ValueError(f"{label}: missing key(s) {', '.join(map(repr, missing))}")
    prefix = f"{where}." if where else ""
    for key, value in data.items():
        kind = _field_kind(cls, known[key])
        if not _type_ok(kind, value):
            raise ValueError(f"{prefix}{key}: expected {_EXPECTED[kind]}, got {_kind(value)}")
    return data


def parse_resolution(text) -> tuple[int, int]:
    """``"640x480"`` or ``(640, 480)`` -> (640, 480); ValueError naming the bad value."""
    if isinstance(text, str):
        parts = text.lower().replace(" ", "").split("x")
    else:
        try:
            parts = list(text)
        except TypeError:
            parts = [text]
    try:
        if len(parts) != 2:
            raise ValueError
        w, h = (int(p) for p in parts)
    except (TypeError, ValueError):
        raise ValueError(f"resolution: expected WIDTHxHEIGHT like 640x480, got {text!r}") from None
    if w < 1 or h < 1 or w > 65536 or h > 65536:
        raise ValueError(f"resolution: expected 1..65536 pixels per side, got {text!r}")
    return w, h
