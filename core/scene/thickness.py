"""Thickness maps: settings, conventions and the analytic expectation of a baked map.

The map is ambient occlusion with the normals flipped inwards (Barré-Brisebois & Bouchard,
GDC 2011; docs/references.md §4), baked by Cycles' Ambient Occlusion shader node with
``inside`` set. Pure Python and NumPy: the Blender side lives in ``blender/bake.py``.

What Cycles computes (``intern/cycles/kernel/svm/ao.h``, ``svm_ao``, Blender 4.x/5.x): with
``inside`` the normal is negated; each of the node's N rays takes a point of the unit disk
(``concentric_sample_disk``) and lifts it onto the hemisphere, D = (x, y, sqrt(1 - x^2 - y^2)),
which is Malley's method: directions are cosine-weighted, pdf cos(theta)/pi. A ray is
*unoccluded* when nothing is hit before the node's Distance (``tmax``); with Only Local only the
shading object's own triangles count. The AO output is ``unoccluded / N``: 1 where nothing is
near (thick), 0 where everything is (thin). So:

- ``thickness`` convention (1 = thick) is the AO output itself;
- ``translucency`` convention (1 = thin, what STA multiplies the back light with) is 1 - AO.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: convention -> what 1 means, and how it is made from Cycles' inside-AO output.
CONVENTIONS = {
    "translucency": "1 = thin (1 - inside AO; STA's convention)",
    "thickness": "1 = thick (inside AO)",
}
TARGETS = ("attribute", "image")
#: What the map is measured from. "ao": Cycles' inside ambient occlusion (STA's local thickness).
#: "ray": the distance to the far side along the inward normals, ray cast per vertex, written as
#: the AO a slab of that thickness gives, 1 - (min(x, D) / D)^2 in the translucency convention
#: (``slab_unoccluded_fraction``): the same values on a slab, but a tube or a ball reads its
#: through-thickness instead of the short chords that occlude its AO (docs/references.md §14).
SOURCES = {
    "ao": "Cycles Ambient Occlusion node, Inside (STA's local thickness)",
    "ray": "distance to the far side along the inward normals, as a slab of that thickness bakes",
}


def default_source(target: str) -> str:
    """The source a bake uses when none is chosen: "ray" for the attribute target, "ao" for an
    image (the ray source measures at vertices only). Chosen by the fidelity suite and the back-lit
    and energy scenes outside it (docs/references.md §14): on slabs both read the same, on tubes and
    balls the AO map reads 0.4-0.65 of the through-thickness, which made every technique that reads
    the map worse than no SSS on back-lit tubes."""
    return "ray" if target == "attribute" else "ao"


#: Image formats and their bit depth: float32 OpenEXR, or 16-bit PNG (linear, Non-Color).
IMAGE_FORMATS = {"OPEN_EXR": ".exr", "PNG": ".png"}
#: Largest ray count of one AO node evaluation used per render sample (the node allows 128);
#: keeping it moderate leaves several render samples, which jitter the position inside a texel.
MAX_NODE_SAMPLES = 16
MAX_SAMPLES = 4096


def check_convention(convention: str) -> str:
    if convention not in CONVENTIONS:
        raise ValueError(f"thickness convention: {convention!r} is not one of {', '.join(CONVENTIONS)}")
    return convention


@dataclass(frozen=True)
class BakeSettings:
    """What to bake and how. Lengths in scene units.

    ``samples``: AO rays per texel or vertex (split by ``split_samples`` into render samples x
    node samples). ``distance_su``: the AO node's Distance; 0 means automatic, a quarter of the
    diagonal of the object's bounding box in world space (``auto_distance_su``). ``only_local``: only the
    object itself occludes (else every object the scene renders). ``target``: a float colour
    attribute named ``attribute_name`` on the mesh (point domain; no UV map needed) or an image
    over the active UV map, ``resolution_px`` square, ``margin_px`` bleed, written into
    ``image_folder`` (a path Blender understands, ``//`` = beside the .blend file) as
    ``image_format``. ``link_materials``: add the result to the object's materials, feeding a
    Shader AOV output named ``aov_name`` (the render passes' thickness AOV). ``source``: what the
    map is measured from (``SOURCES``; "ray" needs the attribute target and ignores ``samples``
    and ``only_local``); None (the default) takes ``default_source(target)``. ``overwrite``: the
    image target may replace files in ``image_folder`` that SSS Lab did not bake from the same mesh
    (without it such a file stops the bake before anything runs; a map SSS Lab baked from the same
    mesh, as its sidecar JSON says, is baked again).
    """

    target: str = "attribute"
    convention: str = "translucency"
    samples: int = 32
    distance_su: float = 0.0
    only_local: bool = True
    attribute_name: str = "Thickness"
    resolution_px: int = 1024
    margin_px: int = 16
    image_format: str = "OPEN_EXR"
    image_folder: str = "//thickness"
    link_materials: bool = True
    aov_name: str = "Thickness"
    source: str | None = None
    overwrite: bool = False

    def __post_init__(self):
        if self.target not in TARGETS:
            raise ValueError(f"bake target: {self.target!r} is not one of {', '.join(TARGETS)}")
        if self.source is None:
            object.__setattr__(self, "source", default_source(self.target))
        if self.source not in SOURCES:
            raise ValueError(f"bake source: {self.source!r} is not one of {', '.join(SOURCES)}")
        if self.source == "ray" and self.target != "attribute":
            raise ValueError(
                "bake source 'ray' measures the thickness at the mesh's vertices: use the attribute target"
                " (or the 'ao' source for an image)"
            )
        check_convention(self.convention)
        _integer(self.samples, "samples", 1, MAX_SAMPLES)
        if not (isinstance(self.distance_su, (int, float)) and math.isfinite(self.distance_su)):
            raise ValueError(f"distance_su: expected a finite number >= 0 (0 = automatic), got {self.distance_su!r}")
        if self.distance_su < 0:
            raise ValueError(f"distance_su: expected a number >= 0 (0 = automatic), got {self.distance_su!r}")
        _integer(self.resolution_px, "resolution_px", 1, 16384)
        _integer(self.margin_px, "margin_px", 0, 64)
        if self.image_format not in IMAGE_FORMATS:
            raise ValueError(f"image_format: {self.image_format!r} is not one of {', '.join(IMAGE_FORMATS)}")
        for name in ("attribute_name", "aov_name"):
            value = getattr(self, name)
            if not isinstance(value, str) or not value.strip() or len(value) > 63:
                raise ValueError(f"{name}: expected a non-empty name of at most 63 characters, got {value!r}")
        if self.target == "image" and not (isinstance(self.image_folder, str) and self.image_folder.strip()):
            raise ValueError(f"image_folder: expected a folder for the baked images, got {self.image_folder!r}")

    @property
    def meaning(self) -> str:
        return CONVENTIONS[self.convention]


def _integer(value, name: str, lo: int, hi: int) -> None:
    if not isinstance(value, int) or isinstance(value, bool) or not lo <= value <= hi:
        raise ValueError(f"{name}: expected an integer in {lo}..{hi}, got {value!r}")


def split_samples(samples: int, *, max_node_samples: int = MAX_NODE_SAMPLES) -> tuple[int, int]:
    """(render samples, AO node samples) whose product is exactly ``samples``.

    Cycles draws the node's rays from the same stratified sequence as the render samples
    (``path_branched_rng_2D``: index = sample * N + ray), so only the product matters for the
    noise; the node loop is cheaper than a render sample, hence the largest node count
    <= ``max_node_samples`` that divides ``samples``.
    """
    _integer(samples, "samples", 1, MAX_SAMPLES)
    node = max(d for d in range(1, min(samples, max_node_samples) + 1) if samples % d == 0)
    return samples // node, node


def auto_distance_su(corners_su) -> float:
    """Default AO distance: a quarter of the diagonal of the axis-aligned box around ``corners_su``.

    ``corners_su`` is (N, 3), e.g. the 8 world-space corners of Blender's ``bound_box``. Why a
    quarter: parts thinner than the distance come out translucent, so it should be about the
    thickness of the object's thick core. For a cube of side s it is 0.433 s: from a face's
    centre no ray that short reaches another face (the opposite face is s away, the side faces
    at least s/2), so the centre is fully thick, while a part a tenth of s thick keeps
    translucency 1 - (0.1 / 0.433)^2 = 0.95 (``slab_unoccluded_fraction``). Half the diagonal
    (the bounding sphere's radius) made even a cube's faces mostly translucent. Returns 0.0 for
    a point-like object (no extent).
    """
    c = np.asarray(corners_su, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3 or c.shape[0] < 1 or not np.all(np.isfinite(c)):
        raise ValueError(f"corners_su: expected finite (N, 3) coordinates, got shape {c.shape}")
    return float(0.25 * np.linalg.norm(c.max(axis=0) - c.min(axis=0)))


def slab_unoccluded_fraction(thickness_su, distance_su: float) -> np.ndarray:
    """Expected inside-AO output on a face of a slab of thickness ``thickness_su``: float64.

    Derivation: at a point of one face, far (> ``distance_su``) from the slab's rim, a ray at
    angle theta to the inward normal reaches the opposite face after t / cos(theta). It stays
    unoccluded iff t / cos(theta) >= D, i.e. cos(theta) <= t / D. Cycles' directions are
    cosine-weighted (module docstring), so mu = cos(theta) has density 2 mu on [0, 1] and
    P(mu <= c) = c^2. Hence AO = (t / D)^2 for t < D and 1 for t >= D (0 for t = 0).
    (Uniform hemisphere sampling would give t / D instead.)
    """
    d = float(distance_su)
    if not (math.isfinite(d) and d > 0):
        raise ValueError(f"distance_su: expected a finite number > 0, got {distance_su!r}")
    t = np.asarray(thickness_su, dtype=np.float64)
    if np.any(~np.isfinite(t)) or np.any(t < 0):
        raise ValueError(f"thickness_su: expected finite values >= 0, got {thickness_su!r}")
    return np.minimum(t / d, 1.0) ** 2


def to_convention(ao, convention: str) -> np.ndarray:
    """Inside-AO values (float, 0..1) in ``convention``: float32, same shape, input not mutated."""
    a = np.asarray(ao, dtype=np.float32)
    return (np.float32(1.0) - a) if check_convention(convention) == "translucency" else a.copy()


def binomial_sigma(p, rays: int) -> np.ndarray:
    """Standard deviation of the unoccluded fraction of ``rays`` independent rays that each
    escape with probability ``p``: sqrt(p (1 - p) / rays). Cycles' stratified sequence does
    better than independent rays, so this bounds the noise of a baked value from above in
    practice (measured on slabs, standard deviation over vertices: 0.5 to 0.8 of it at 16 rays,
    0.2 to 0.3 of it at 256)."""
    _integer(rays, "rays", 1, 1 << 30)
    q = np.asarray(p, dtype=np.float64)
    return np.sqrt(q * (1.0 - q) / rays)


def bakers_map(values, convention: str) -> np.ndarray:
    """A baked map in the convention of the thickness bakers artists know (Substance, Marmoset:
    white = thick, docs/references.md §19): the slab thickness the value stands for over the bake
    distance D, min(t, D) / D = sqrt(inside AO) (``slab_unoccluded_fraction`` inverted). Linear in
    the thickness, so an engine's remap 0..D (HDRP's Thickness Remap) gives it back. float32, same
    shape, input not mutated; values outside 0..1 are refused."""
    v = np.asarray(values, dtype=np.float64)
    if v.size and (not np.all(np.isfinite(v)) or v.min() < 0 or v.max() > 1):
        raise ValueError(f"values: expected a baked map in 0..1, got values in {v.min():.4g}..{v.max():.4g}")
    ao = 1.0 - v if check_convention(convention) == "translucency" else v
    return np.sqrt(ao).astype(np.float32)


def object_thickness_su(values, convention: str, distance_su: float) -> np.ndarray:
    """The slab thickness (scene units, at most D) a baked map stands for: D sqrt(inside AO), what
    EEVEE's Thickness socket reads (an object-space length, docs/references.md §19)."""
    d = float(distance_su)
    if not (math.isfinite(d) and d > 0):
        raise ValueError(f"distance_su: expected the bake distance, a finite number > 0, got {distance_su!r}")
    return (np.float32(d) * bakers_map(values, convention)).astype(np.float32)
