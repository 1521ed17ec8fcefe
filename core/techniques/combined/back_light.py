"""The combined technique's light from behind on the compiled backend (its ``_kernels.py``).

``core.techniques.combined.technique.back_light`` and ``BackLight.transmitted`` are the readable NumPy reference; here
the same computation runs as fused per-pixel kernels on the bounding box of the mask's pixels
(the region), parallel over rows, with nothing the size of a frame in float64: the far side's
thickness and normal, the irradiance from behind (``back_light_pixels``), the transmittance's
table reads, the view cosine and the range of the spread's widths per row and object
(``transmit_pixels``), the spread per object confined to what its pixels read (the reference's
pyramid for its wide levels first: ``spread_pyramid``, ``blur_reduced``; then down the object's
rows in bands of ``SPREAD_BAND``, its vertical running sums carried from band to band:
``band_sigma``, ``spread_band``, ``spread_reduced_part``, ``part_results``, so that the widths,
the level planes and the results are held for a band, not for the object) and the exit weight
and scale (``finish_light``). Each kernel computes the reference's float32 and float64
operations in its order, so the result is the reference's to the bit: in check mode
(``core.compute.backend``) every ``transmitted`` and ``add_to`` is compared with the reference's with a
bound of 0.

The far side's largest curvature is computed a few rows at a time (``largest_rows``, its column
sums carried from rows to rows). ``transmitted`` and ``add_to`` hold the irradiance and the
curvature on the whole region, for the many lengths the fit tries; the last ``add_to``
(``combined``'s) on a region of ``STREAM_FROM_PIXELS`` or more holds neither: it goes down the
region in bands of rows and computes the light
again where it is read (``CompiledBackLight._stream``: once for the parts' widths, once for the
pyramid's blocks, once for the bands' running sums), each band's result added to the frame
(``finish_band``), so that at 4K it holds the pyramid, a band's buffers and the running sums
instead of two frames' worth of float32.

Without a medium (Burley's law) the reference's exponentials are NumPy's vectorized ones, which
a kernel does not reproduce to the bit: that case stays on the NumPy code, as do inputs whose
shapes the reference would reject (it then raises its own error).
"""

from __future__ import annotations

import contextlib
import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ... import optics
from ...base import arrays
from ...compute import backend
from ...optics.transmittance import (
    COSINE_ENTRY,
    DISK_U,
    ENTRY_COSINES,
    ROUGH_ENTRY,
    ROUGH_VIEW_COSINES,
    TAUS,
    disk_table,
    lateral_table,
    legacy_single_scattering_albedo,
    passage_column,
    single_scattering_albedo,
    walk_medium,
)
from ...scene.scene import Light
from .pyramid import box_radius, coarse_radii, full_levels, pyramid_layout, spread_levels


def _kernels():
    """This package's compiled kernels (``_kernels.py``), loaded on first use."""
    return backend.kernels(__package__)


def _spread_kernels():
    """The compiled kernels of the spread (``_spread_kernels.py``), loaded on first use."""
    return backend.kernels(__package__, "_spread_kernels")


def _optics_kernels():
    """The shared physics' compiled kernels (``core/optics/_kernels.py``), loaded on first use."""
    return backend.kernels(optics.__name__)


_c = np.ascontiguousarray


def _spans_box(lo: np.ndarray, hi: np.ndarray) -> tuple[int, int, int, int] | None:
    """(first row, last row + 1, first column, last column + 1) of per-row spans [lo, hi)."""
    rows = np.flatnonzero(hi > lo)
    if not rows.size:
        return None
    return int(rows[0]), int(rows[-1]) + 1, int(lo[rows].min()), int(hi[rows].max())


def _camera_vector(camera) -> np.ndarray:
    """``core.techniques.combined._kernels._view_vector``'s camera: (orthographic, position (3), -forward (3))
    float32."""
    cam = np.zeros(7, np.float32)
    if camera is not None:
        cam[0] = 1.0 if camera.type == "ORTHO" else 0.0
        cam[1:4] = camera.position.astype(np.float32)
        cam[4:7] = (-camera.forward).astype(np.float32)
    return cam


#: Rows of the far side's box ``core.optics._kernels.largest_rows`` computes at a time.
CURVATURE_ROWS = 32


class _Curvature:
    """``core.optics.energy.surface_curvature``'s largest curvature (radius 1) on the far side's box
    (``box``: rows y0..y1 - 1, columns x0..x1 - 1 of the frame) of its pixels (``mask`` with finite
    normal and position), as ``core.techniques.combined.technique.far_side`` reads it, row by row:
    ``core.optics._kernels.largest_rows``, which carries its column sums from one call to the next, so
    that rows asked for in ascending order are each computed once and nothing of the box's size
    is held (equal to the bit to the whole box's sums)."""

    def __init__(self, mask, normal, position, box):
        self.inputs = (normal, position, mask)
        self.box = box
        self.h, self.w = box[1] - box[0], box[3] - box[2]
        self.carry = np.zeros((2, self.w), np.float64)
        self.done = 0
        self.cums = np.empty((2, 0, self.w), np.float64)

    def rows(self, a: int, b: int, out: np.ndarray) -> None:
        """The box's rows ``a``..``b`` - 1 into ``out`` (``b`` - ``a``, columns) float32, at most
        ``CURVATURE_ROWS`` at a time (the running sums they read: 2 float64 planes of as many rows)."""
        if self.done > max(a - 1, 0):  # rows above what is carried: sum again from the box's top
            self.carry[:] = 0.0
            self.done = 0
        y0, _, x0, _ = self.box
        for c0 in range(a, b, CURVATURE_ROWS):
            c1 = min(c0 + CURVATURE_ROWS, b)
            need = min(c1 + 1, self.h) - max(c0 - 1, 0) + 1
            if self.cums.shape[1] < need:
                self.cums = np.empty((2, need, self.w), np.float64)
            backend.run_kernel(
                _optics_kernels().largest_rows,
                *self.inputs, y0, x0, self.h, self.w, c0, c1, self.carry, self.done, self.cums,
                out[c0 - a : c1 - a],
            )  # fmt: skip
            self.done = max(c1 - 1, 0)


@functools.lru_cache(maxsize=32)
def _passage_columns(alphas: tuple[float, ...], entries: tuple) -> np.ndarray:
    """``passage_column`` of each channel's albedo ``alphas`` and each of ``entries``, float64
    (channels, entries, ``TAUS``), kept for the media seen last, since every ``CompiledBackLight``
    of a material reads the same (``core.pipeline.auto``'s features build one per material and frame, and
    these reads were a fifth of their light from behind on the blocks). Read-only: its callers
    take a copy (a read-only array is another type to the kernels, compiled again)."""
    columns = np.zeros((len(alphas), len(entries), TAUS.size), np.float64)
    for c, alpha in enumerate(alphas):
        for g, entry in enumerate(entries):
            columns[c, g] = passage_column(alpha, entry)
    columns.flags.writeable = False
    return columns


def _largest_curvature(mask, normal, position, box) -> np.ndarray:
    """The far side's largest curvature on its whole ``box`` (``_Curvature``), float32; in check
    mode compared with ``surface_curvature``."""
    from ...optics.energy import surface_curvature

    y0, y1, x0, x1 = box
    out = np.empty((y1 - y0, x1 - x0), np.float32)
    rows = _Curvature(mask, normal, position, box)
    for a in range(0, y1 - y0, CURVATURE_ROWS):
        rows.rows(a, min(a + CURVATURE_ROWS, y1 - y0), out[a : a + CURVATURE_ROWS])
    if backend.active() == "check":
        window = slice(y0, y1), slice(x0, x1)
        far = mask[window] & arrays.finite_pixels(normal[window], position[window])
        with backend.use("numpy"):
            reference = surface_curvature(normal[window], position[window], far, radius_px=1)[1]
        backend.compare("largest curvature", reference, out, np.zeros(out.shape))
    return out


def compiled_back_light(t, distance, **a) -> CompiledBackLight | None:
    """``core.techniques.combined.technique.back_light(**a)`` on the compiled backend (``t`` the thickness map as
    float32 (H, W), ``distance`` the bake's distance, both checked), or None where the NumPy code
    must run (no medium, or inputs whose shapes it rejects)."""
    from ...optics.energy import CHORD_CAP

    medium, camera = a["medium"], a["camera"]
    if medium is None:
        return None
    n = arrays.image(a["normal"], "normal")
    shape = n.shape[:2]
    if t.shape != shape:
        return None
    p = arrays.image(a["position"], "position")
    arrays.same_size(shape, position=p)
    m = arrays.mask_array(a["mask"], shape)
    z = None
    if a["depth"] is not None:
        z = arrays.image(a["depth"], "depth", None)
        if z.shape != shape:
            return None
    ids = None
    if a["object_id"] is not None:
        ids = np.asarray(a["object_id"])
        ids = ids[..., 0] if ids.ndim == 3 else ids
        if ids.shape != shape or ids.dtype.kind not in "fiub":
            return None
    albedo = None
    if a["albedo"] is not None:
        albedo = arrays.image(a["albedo"], "albedo")
        arrays.check_albedo_mode(a["albedo_mode"])
        arrays.same_size(shape, albedo=albedo)
    lights = list(a["lights"])
    for light in lights:
        if not isinstance(light, Light):
            raise ValueError(f"lights: expected core.scene.scene.Light entries, got {type(light).__name__}")
    as_thickness = a["thickness_convention"] == "thickness"
    mc, nc, pc, tc = _c(m), n, p, t
    spans = np.empty((shape[0], 4), np.int64)
    backend.run_kernel(_kernels().back_light_spans, mc, nc, pc, tc, spans)
    far = _spans_box(spans[:, 0], spans[:, 1])
    region = _spans_box(spans[:, 2], spans[:, 3])
    kmin = 2.0 / (CHORD_CAP * float(distance))
    back = CompiledBackLight(
        shape=shape,
        medium=medium,
        camera=camera,
        mask=mc,
        normal=nc,
        position=pc,
        thickness=tc,
        as_thickness=as_thickness,
        distance=float(distance),
        kmin=kmin,
        far=far if camera is not None else None,
        cam=_camera_vector(camera),
        region=region,
        depth=z,
        ids=ids,
        albedo=albedo,
        pre_post=a["albedo_mode"] == "pre-post",
        table=_optics_kernels().light_table([light for light in lights if light.energy > 0]),
    )
    if region is None:
        return back
    y0, y1, x0, x1 = region
    if z is not None and camera is not None:
        back.parted = True
        if ids is not None:
            inside = m[y0:y1, x0:x1] & np.isfinite(t[y0:y1, x0:x1])
            found = np.unique(ids[y0:y1, x0:x1][inside])
            back.part_ids = _c(found[~np.isnan(found)] if found.dtype.kind == "f" else found)
            back.ids_c = _c(ids)
    return back


def _needed_levels(grid: np.ndarray, least: np.ndarray, most: np.ndarray) -> np.ndarray:
    """(levels, 4) bool: which blur levels of ``grid`` a channel's pixels interpolate between,
    their widths from ``least`` to ``most`` per channel (clipped to the last level, as the
    reference's are); the last column: any channel (the mask's blur)."""
    needed = np.zeros((grid.size, 4), bool)
    top = grid[-1]
    for c in range(3):
        if not least[c] <= most[c]:
            continue
        lo = np.clip(np.searchsorted(grid, np.clip(float(least[c]), 0.0, top), side="left"), 1, grid.size - 1)
        hi = np.clip(np.searchsorted(grid, np.clip(float(most[c]), 0.0, top), side="left"), 1, grid.size - 1)
        needed[max(lo - 1, 1) : hi + 1, c] = True
    needed[:, 3] = needed[:, :3].any(axis=1)
    return needed


def _row_levels(grid: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(rows, 2) int64: per row the first and last blur level of ``grid`` its pixels interpolate
    between, from its widths' range per channel ``rows`` (rows, 3, (least, most); least > most
    where the row has no pixel: then none)."""
    top = grid[-1]
    least = np.clip(np.nan_to_num(rows[..., 0], posinf=top), 0.0, top)
    most = np.clip(rows[..., 1], 0.0, top)
    lo = np.clip(np.searchsorted(grid, least, side="left"), 1, grid.size - 1) - 1
    hi = np.clip(np.searchsorted(grid, most, side="left"), 1, grid.size - 1)
    empty = ~(rows[..., 0] <= rows[..., 1])
    lo = np.where(empty, grid.size, np.maximum(lo, 1)).min(axis=1)
    hi = np.where(empty, -1, hi).max(axis=1)
    return np.ascontiguousarray(np.stack([lo, hi], axis=1), np.int64)


def _width_ranges(stats: np.ndarray, fill: np.ndarray) -> np.ndarray:
    """Per row of a part (``transmit_pixels``' ``part_rows`` of its rows) and channel, the smallest
    and the largest of its pixels' widths in pixels (rows, 3, (least, most)) float32, +inf and 0
    where the row has no pixel: ``band_sigma``'s widths, where a NaN width is the part's largest
    ``fill`` (float32) times the pixel's scale. Rounding keeps the order of products by the same
    ``fill`` >= 0, so its smallest and largest are ``fill`` times the smallest and largest scale."""
    out = np.empty((stats.shape[0], 3, 2), np.float32)
    least, most = stats[:, 5:8].astype(np.float32), stats[:, 8:11].astype(np.float32)
    nan_least, nan_most = stats[:, 11:14].astype(np.float32), stats[:, 14:17].astype(np.float32)
    has_nan = np.isfinite(nan_least)
    with np.errstate(invalid="ignore"):
        out[..., 0] = np.where(has_nan, np.minimum(least, fill * nan_least), least)
        out[..., 1] = np.where(has_nan, np.maximum(most, fill * nan_most), most)
    return out


#: Rows of a part the spread goes down at a time (``core.techniques.combined._spread_kernels.spread_band``): its
#: level planes
#: and results are held for a band of rows, not for the part.
SPREAD_BAND = 128

#: The region's size (pixels of the mask's bounding box) from which the last ``add_to`` streams
#: its light (``_stream``) instead of holding it: below it the irradiance and the curvature held
#: whole take at most 16 MB, and computing the light three times would cost more time than that
#: memory is worth; from it the held arrays grow with the frame (133 MB at 4K, on top of the
#: output frame), and streaming keeps the technique within its inputs and two frames.
STREAM_FROM_PIXELS = 1 << 20


@contextlib.contextmanager
def streaming_every_region():
    """Within it, the last ``add_to`` streams on a region of any size: ``core.study.prepare`` compiles
    that path on its small frame. The light added is the same to the bit either way (only the
    time and the memory differ), so a call elsewhere meanwhile loses nothing."""
    global STREAM_FROM_PIXELS
    before = STREAM_FROM_PIXELS
    STREAM_FROM_PIXELS = 0
    try:
        yield
    finally:
        STREAM_FROM_PIXELS = before


def _bands(box, wide, radii, needed, n_full) -> list[tuple[int, int]]:
    """The bands (first row, last row + 1; region rows) ``spread_band`` goes down the part's rows
    ``box[0]``..``box[1]`` - 1 in: ``SPREAD_BAND`` rows each, but a band that ends 3 r rows or
    less before the last row a level's running sums read (half-width r, ``wide`` the
    reference's box) goes to the part's end."""
    ends = [
        min(box[1] + 2 * int(radii[k - 1]), int(wide[1])) - 3 * int(radii[k - 1])
        for k in range(1, n_full)
        if needed[k, 3]
    ]
    last = min(ends, default=box[1])
    bands = []
    b0 = box[0]
    while b0 < box[1]:
        b1 = min(b0 + SPREAD_BAND, box[1])
        if b1 >= last:
            b1 = box[1]
        bands.append((b0, b1))
        b0 = b1
    return bands


def _band_state(radii, needed, n_full, columns) -> tuple[np.ndarray, np.ndarray]:
    """``spread_band``'s running sums carried from band to band, float64, and where each level's
    start (int64 per level): per plane it blurs and strip of ``PART_STRIP`` of the part's
    ``columns``, three rings of 2 r + 2 rows."""
    PART_STRIP = _kernels().PART_STRIP

    at = np.zeros(needed.shape[0], np.int64)
    size = 0
    strips = -(-columns // PART_STRIP)
    for k in range(1, n_full):
        if not needed[k, 3]:
            continue
        at[k] = size
        size += int(needed[k].sum()) * strips * 3 * (2 * int(radii[k - 1]) + 2) * PART_STRIP
    return np.empty(size, np.float64), at


@dataclass
class _Part:
    """What the spread of one part needs before its bands (``CompiledBackLight._part``)."""

    box: tuple[int, int, int, int]
    part: np.ndarray
    fill: np.ndarray
    rows: np.ndarray
    sigmas: list
    grid: np.ndarray
    wide: np.ndarray
    radii: np.ndarray
    needed: np.ndarray
    n_full: int
    levels: np.ndarray
    size: int


@dataclass
class CompiledBackLight:
    """``core.techniques.combined.technique.BackLight`` on the compiled backend: the inputs the kernels read (no
    frame is
    copied), the irradiance from behind on the region (``e``) once a call needs it whole
    (``transmitted``, ``add_to`` but the last), and in check mode the reference's ``BackLight``
    (``reference``). The last ``add_to`` holds nothing of the region's size: it goes down the
    region in bands of rows, computing the light again where it is read (``_stream``)."""

    shape: tuple[int, int]
    medium: Any
    camera: Any
    mask: np.ndarray
    normal: np.ndarray
    position: np.ndarray
    thickness: np.ndarray
    as_thickness: bool
    distance: float
    kmin: float
    #: The far side's box (with a camera: where its curvature is read), or None.
    far: tuple[int, int, int, int] | None
    cam: np.ndarray
    region: tuple[int, int, int, int] | None
    depth: np.ndarray | None
    ids: np.ndarray | None
    albedo: np.ndarray | None
    pre_post: bool
    #: ``core.optics._kernels.light_table`` of the lights with energy > 0.
    table: np.ndarray
    e: np.ndarray | None = None
    largest: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.float32))
    curvature_origin: tuple[int, int] = (0, 0)
    lit_any: bool | None = None
    #: A Depth pass and a camera: the light spreads within ``part_ids`` where a pixel is lit.
    parted: bool = False
    spread: bool = False
    part_ids: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    ids_c: np.ndarray = field(default_factory=lambda: np.zeros((1, 1), np.int64))
    reference: Any = None
    #: The medium's tables (the transmittance's columns, the lateral spread's), read at the first call.
    tables: dict = field(default_factory=dict)

    @property
    def _region(self) -> tuple[int, int, int, int]:
        """The region (there is one wherever the kernels run)."""
        assert self.region is not None
        return self.region

    @property
    def lit(self) -> np.ndarray:
        """Whether a pixel is lit from behind (a 0-d array: ``lit.any()`` as on ``BackLight.lit``)."""
        self._hold()
        return np.array(bool(self.lit_any))

    def _streams(self) -> bool:
        """Whether the region is large enough for the last ``add_to`` to stream its light."""
        assert self.region is not None
        y0, y1, x0, x1 = self.region
        return (y1 - y0) * (x1 - x0) >= STREAM_FROM_PIXELS

    def _hold(self) -> None:
        """The far side's curvature and the irradiance from behind on the whole region (``e``)."""
        if self.e is not None or self.region is None:
            self.lit_any = bool(self.lit_any)
            return
        y0, y1, x0, x1 = self.region
        if self.far is not None:
            self.largest = _largest_curvature(self.mask, self.normal, self.position, self.far)
            self.curvature_origin = (self.far[0], self.far[2])
        e = np.empty((y1 - y0, x1 - x0, 3), np.float32)
        lit_rows = np.empty(y1 - y0, bool)
        self._irradiance(self.largest, *self.curvature_origin, y0, e, lit_rows)
        self.e = e
        self.lit_any = bool(lit_rows.any())
        self.spread = self.parted and self.lit_any

    def _irradiance(self, largest, cy0, cx0, fy0, e, lit_rows) -> None:
        """``back_light_pixels`` on the region's columns, frame rows from ``fy0``, into ``e``."""
        walks = self.camera is not None and self.medium.walks
        backend.run_kernel(
            _kernels().back_light_pixels, self.mask, self.normal, self.position, self.thickness, self.as_thickness,
            self.distance, self.kmin, walks, self.cam, largest, cy0, cx0, self.table, fy0, self._region[2], e, lit_rows,
        )  # fmt: skip

    def transmitted(self, d_su, transmission_scale=1.0) -> np.ndarray:
        """``core.techniques.combined.technique.BackLight.transmitted``."""
        out = np.zeros(self.shape + (3,), np.float32)
        self._into(out, d_su, transmission_scale, add=False, last=False)
        if self.reference is not None:
            reference = self.reference.transmitted(d_su, transmission_scale)
            backend.compare("light from behind", reference, out, np.zeros(out.shape))
        return out

    def add_to(self, out: np.ndarray, d_su, transmission_scale=1.0, *, last: bool = False) -> None:
        """``core.techniques.combined.technique.BackLight.add_to``: ``out`` += the transmitted light, in place."""
        expected = None
        if self.reference is not None:
            expected = out + self.reference.transmitted(d_su, transmission_scale)
        self._into(out, d_su, transmission_scale, add=True, last=last)
        if expected is not None:
            backend.compare("light from behind (added)", expected, out, np.zeros(out.shape))

    def _into(self, out, d_su, transmission_scale, *, add: bool, last: bool) -> None:
        scale = arrays.rgb_lengths(transmission_scale, "transmission_scale").astype(np.float32)
        medium = self.medium
        walks = medium.walks
        if walks:
            skin = medium.method == "RANDOM_WALK_SKIN"
            ell, alpha = walk_medium(
                d_su,
                medium.base_color,
                ior=medium.ior,
                anisotropy=medium.anisotropy,
                cosine_share=0.5 if skin else 0.0,
                legacy=medium.method == "RANDOM_WALK_LEGACY",
            )
            if skin:
                grid = np.asarray(ROUGH_VIEW_COSINES, np.float64)
                ior = round(float(medium.ior), 2)
                entries: list = [(ROUGH_ENTRY, ior, g) for g in ROUGH_VIEW_COSINES] + [COSINE_ENTRY]
            else:
                grid = np.asarray(ENTRY_COSINES, np.float64)
                entries = list(ENTRY_COSINES)
            # The tables depend on the medium, not on the length: read once per BackLight.
            columns = self.tables.get("columns")
            if columns is None:
                columns = _passage_columns(tuple(float(a) for a in alpha), tuple(entries)).copy()
                self.tables["columns"] = columns
            nodes = TAUS
            kind = 1 if skin else 0
        else:
            ell = arrays.rgb_lengths(d_su, "transmission_d_su").astype(np.float64)
            grid = np.zeros(1, np.float64)
            columns = np.broadcast_to(disk_table()[0], (3, 1, DISK_U.size)).copy()
            nodes = DISK_U
            kind = 2
        spread_len = arrays.rgb_lengths(d_su, "transmission_d_su").astype(np.float64)
        weight = self.albedo is not None
        albedo = self.albedo if weight else np.zeros((1, 1, 3), np.float32)
        base = np.asarray(medium.base_color, np.float32)
        finish = (albedo, self.pre_post, walks, base, weight, scale, bool(np.any(scale != 1)), add)
        transmit = self._transmit_arguments(kind, ell, grid, columns, nodes, spread_len)
        if last and add and self.e is None and self.region is not None and self._streams():
            self._stream(transmit, finish, out)
            return
        self._hold()
        if self.region is not None:
            light = self._light(transmit, last)
        else:
            light = np.zeros((0, 0, 3), np.float32)
        y0, x0 = (0, 0) if self.region is None else self._region[::2]
        backend.run_kernel(_kernels().finish_light, light, y0, x0, *finish, out)

    def _transmit_arguments(self, kind, ell, grid, columns, nodes, spread_len) -> tuple:
        """``transmit_pixels``' arguments after the curvature's origin up to ``spread`` (excluded),
        and then from ``spread_len`` to ``focal``, as (view, ..., nodes), (spread_len, ..., focal)."""
        medium = self.medium
        if self.parted and medium.walks:
            if "lateral" not in self.tables:
                alpha = single_scattering_albedo(medium.base_color, medium.anisotropy)
                if medium.method == "RANDOM_WALK_LEGACY" and medium.anisotropy >= 0:
                    alpha = legacy_single_scattering_albedo(medium.base_color, medium.anisotropy)
                tables = [lateral_table(alpha[c]) for c in range(3)]
                values = np.zeros((3, TAUS.size), np.float64)
                for c, v in enumerate(tables):
                    values[c, : v.size] = v
                self.tables["lateral"] = (np.array([v.size for v in tables], np.int64), values)
            counts, values = self.tables["lateral"]
            spread_nodes = TAUS
        elif self.parted:
            m2 = disk_table()[1]
            counts = np.full(3, DISK_U.size, np.int64)
            values = np.broadcast_to(m2, (3, m2.size)).copy()
            spread_nodes = DISK_U
        else:
            counts = np.zeros(3, np.int64)
            values = np.zeros((3, 1), np.float64)
            spread_nodes = np.zeros(1, np.float64)
        view = self.camera is not None and medium.walks
        ior2 = float(medium.ior) * float(medium.ior)
        camera = self.camera
        ortho = camera is not None and camera.type == "ORTHO"
        focal = np.float32(0.0 if camera is None else camera.ortho_px_per_unit if ortho else camera.focal_px)
        depth = self.depth if self.parted else np.zeros((1, 1), np.float32)
        first = (view, self.cam, kind, ior2, _c(ell), grid, columns, nodes)
        widths = (kind, _c(spread_len), counts, spread_nodes, values)
        second = (*widths[1:], self.ids_c, self.part_ids, depth, ortho, focal)
        return first, second, widths

    def _transmit(self, transmit, largest, cy0, cx0, fy0, e, light, spread, part_rows) -> None:
        """``transmit_pixels`` on the region's columns, frame rows from ``fy0``."""
        first, second, _ = transmit
        backend.run_kernel(
            _kernels().transmit_pixels, e, self.mask, self.normal, self.position, self.thickness, self.as_thickness,
            self.distance, self.kmin, largest, cy0, cx0, fy0, self._region[2], *first, spread, *second, light,
            part_rows,
        )  # fmt: skip

    def _part(self, part_rows, p) -> _Part | None:
        """Part ``p``'s box, widths and levels from ``transmit_pixels``' rows, or None where its
        light does not spread (no pixel, or every width below the first level)."""

        assert self.region is not None
        y0, _, x0, _ = self._region
        h, w = self.shape
        box = _spans_box(part_rows[:, p, 0].astype(np.int64), part_rows[:, p, 1].astype(np.int64))
        if box is None:
            return None
        fill = part_rows[:, p, 2:5].max(axis=0).astype(np.float32)
        rows = _width_ranges(part_rows[box[0] : box[1], p], fill)
        least, most = rows[..., 0].min(axis=0), rows[..., 1].max(axis=0)
        top = float(most.max(initial=0.0))
        sigmas = spread_levels(top)
        if len(sigmas) == 1:
            return None
        # The reference's box: the part's, widened by the widest blur's reach, within the frame.
        pad = int(math.ceil(6.0 * top)) + 3
        wide = np.array(
            [
                max(y0 + box[0] - pad, 0) - y0,
                min(y0 + box[1] - 1 + pad + 1, h) - y0,
                max(x0 + box[2] - pad, 0) - x0,
                min(x0 + box[3] - 1 + pad + 1, w) - x0,
            ],
            np.int64,
        )
        radii = np.array([box_radius(sg) for sg in sigmas[1:]], np.int64)
        grid = np.asarray(sigmas, np.float64)
        needed = _needed_levels(grid, least, most)
        levels, size = pyramid_layout(sigmas, wide, needed[:, 3])
        return _Part(
            box, np.array(box, np.int64), fill, rows, sigmas, grid, wide, radii, needed, full_levels(sigmas), levels,
            size,
        )  # fmt: skip

    def _on(self, p, part, a, b, on) -> None:
        """``on``'s first ``b`` - ``a`` rows: part ``p``'s pixels in region rows ``a``..``b`` - 1 and
        the columns of its box ``part``."""
        rows = np.array([a, b, part[2], part[3]], np.int64)
        y0, _, x0, _ = self._region
        backend.run_kernel(
            _kernels().part_pixels,
            self.mask,
            self.thickness,
            self.ids_c,
            self.part_ids,
            p,
            self.ids is None,
            y0,
            x0,
            rows,
            on,
        )

    def _blur_levels(self, q: _Part, flat) -> None:
        """``blur_reduced`` of each reduced level of ``flat`` (``_reduced_levels``' second half)."""

        for k in range(q.n_full, len(q.sigmas)):
            f, off, hc, wc = (int(v) for v in q.levels[k - q.n_full])
            if f == 0:
                continue
            radii = np.array(coarse_radii(q.sigmas[k], f), np.int64)
            backend.run_kernel(
                _spread_kernels().blur_reduced,
                radii,
                flat[off : off + 4 * hc * wc].reshape(4, hc, wc),
            )

    def _bands_of(self, q: _Part, p, light, l0, on, o0, curvature, flat, band_light) -> None:
        """The spread of part ``p`` down its bands of rows: ``band_sigma``, ``spread_band``,
        ``spread_reduced_part``, ``part_results``; ``light`` and ``on`` hold (or, by
        ``band_light(b0, b1, reach)``, are given before each band) the rows the band reads, from
        region rows ``l0`` and ``o0`` (``band_light`` returns them); ``curvature`` = (largest, cy0,
        cx0), or a callable giving it for the band. After each band ``band_light(b0, b1, None)``
        finishes its rows, when given."""
        _, _, widths = self._transmit_cache
        box, part, wide, radii, needed, n_full = q.box, q.part, q.wide, q.radii, q.needed, q.n_full
        state, at = _band_state(radii, needed, n_full, box[3] - box[2])
        row_levels = _row_levels(q.grid, q.rows)
        bands = _bands(box, wide, radii, needed, n_full)
        most_rows = max(b1 - b0 for b0, b1 in bands)
        reach = max((3 * int(radii[k - 1]) for k in range(1, n_full) if needed[k, 3]), default=0)
        band_planes = np.empty((4, most_rows, box[3] - box[2]), np.float32)
        columns = self._region[3] - self._region[2]
        band_out = np.empty((most_rows, columns, 3), np.float32)
        band_sig = np.empty((most_rows, columns, 3), np.float32)
        y0, _, x0, _ = self._region
        camera = self.camera
        ortho = camera is not None and camera.type == "ORTHO"
        focal = np.float32(0.0 if camera is None else camera.ortho_px_per_unit if ortho else camera.focal_px)
        for b0, b1 in bands:
            if band_light is not None:
                light, l0, on, o0, curvature = band_light(b0, b1, reach)
            largest, cy0, cx0 = curvature
            out = band_out[: b1 - b0]
            sig = band_sig[: b1 - b0]
            backend.run_kernel(
                _kernels().band_sigma, self.mask, self.normal, self.position, self.thickness, self.as_thickness,
                self.distance, self.kmin, largest, cy0, cx0, y0, x0, *widths, self.ids_c, self.part_ids, p,
                self.ids is None, self.depth, ortho, focal, q.fill, part, b0, b1, sig,
            )  # fmt: skip
            backend.run_kernel(
                _spread_kernels().spread_band,
                light, sig, on, part, wide, q.grid, n_full, radii, needed, row_levels, b0, b1,
                state, at, band_planes, out, l0, o0,
            )  # fmt: skip
            # The band's rows as one part of their own, in the band's coordinates.
            band = np.array([0, b1 - b0, box[2], box[3]], np.int64)
            band_box = np.array([wide[0] - b0, wide[1] - b0, wide[2], wide[3]], np.int64)
            band_on = on[b0 - o0 : b1 - o0]
            rows = light[b0 - l0 : b1 - l0]
            if n_full < len(q.sigmas):
                backend.run_kernel(
                    _spread_kernels().spread_reduced_part,
                    rows, sig, band_on, band, band_box, q.grid, n_full, flat, q.levels, out,
                )  # fmt: skip
            # Nothing reads these rows of the light again: the next bands' running sums have
            # passed them, and the reduced levels are made.
            backend.run_kernel(_kernels().part_results, rows, band_on, band, out)
            if band_light is not None:
                band_light(b0, b1, None)

    def _light(self, transmit, last) -> np.ndarray:
        """The transmitted light on the region after its spread, float32 (rows, columns, 3), from
        the irradiance held whole (``e``; with ``last`` in its place)."""
        assert self.region is not None and self.e is not None
        y0, y1, x0, x1 = self.region
        e = self.e
        light = e if last else np.empty(e.shape, np.float32)
        n_parts = self.part_ids.size if self.spread else 0
        part_rows = np.empty((y1 - y0 if self.spread else 1, max(n_parts, 1), 17), np.float64)
        curvature = (self.largest, *self.curvature_origin)
        self._transmit(transmit, *curvature, y0, e, light, self.spread, part_rows)
        if not self.spread:
            return light
        self._transmit_cache = transmit
        for p in range(n_parts):
            q = self._part(part_rows, p)
            if q is None:
                continue
            box = q.box
            on = np.empty((box[1] - box[0], box[3] - box[2]), np.uint8)
            self._on(p, q.part, box[0], box[1], on)
            # The reduced levels first, from the light before the bands below replace it.
            flat = np.empty(q.size, np.float32)
            if np.any(q.levels[:, 0] > 0):
                backend.run_kernel(
                    _spread_kernels().spread_pyramid,
                    light,
                    on,
                    q.part,
                    q.wide,
                    q.levels,
                    flat,
                    0,
                    1 << 62,
                    0,
                    box[0],
                )
                self._blur_levels(q, flat)
            self._bands_of(q, p, light, 0, on, box[0], curvature, flat, None)
        return light

    def _stream(self, transmit, finish, out) -> None:
        """``add_to``'s last call without the region's irradiance held: down the region in bands of
        ``SPREAD_BAND`` rows, the light computed where it is read (``_Rows``) and each band's
        finished light added to ``out``. With a spread, once for the parts' widths (before their
        levels are known), once for each part's reduced levels, once for its bands (holding the
        rows its running sums read ahead), and once for the pixels of no part that spreads:
        equal to the bit to ``_light``, which reads them from the light held whole."""
        assert self.region is not None
        y0, y1, x0, x1 = self.region
        rh, rw = y1 - y0, x1 - x0
        self._transmit_cache = transmit
        mode_rest = 0
        owned = np.zeros(max(self.part_ids.size, 1), bool)
        plans: list = []
        if self.parted:
            # The parts' widths: transmit_pixels on no light (only its rows of widths). The
            # reference spreads only where a pixel is lit; here also where none is (not known
            # before the light is computed): then the light is 0 everywhere, and so is its spread
            # (every level's blur and mask ratio of zeros is +0), as the reference's.
            n_parts = self.part_ids.size
            part_rows = np.empty((rh, n_parts, 17), np.float64)
            rows = _Rows(self, transmit)
            for a in range(0, rh, SPREAD_BAND):
                rows.widths(a, min(a + SPREAD_BAND, rh), part_rows[a : a + SPREAD_BAND])
            del rows
            for p in range(n_parts):
                q = self._part(part_rows, p)
                if q is not None:
                    owned[p] = True
                    plans.append((p, q))
            mode_rest = 2 if plans else 0
        one_part = self.ids is None
        for p, q in plans:
            flat = np.empty(q.size, np.float32)
            self._stream_pyramid(transmit, p, q, flat)
            finish_mode = 0 if one_part and q.box[0] == 0 and q.box[1] == rh else 1
            if finish_mode == 0:
                mode_rest = -1  # every row of the region finished with the part's bands
            self._stream_bands(transmit, p, q, flat, finish, finish_mode, owned, out)
            del flat
        if mode_rest >= 0:
            rows = _Rows(self, transmit)
            buf = np.empty((min(SPREAD_BAND, rh), rw, 3), np.float32)
            for a in range(0, rh, SPREAD_BAND):
                b = min(a + SPREAD_BAND, rh)
                rows.light(a, b, buf[: b - a])
                self._finish(buf[: b - a], y0 + a, mode_rest, np.zeros((1, 1), np.uint8), 0, owned, finish, out)
        if finish[4]:
            albedo, pre_post, walks, base, _, scale, scaled, add = finish
            backend.run_kernel(
                _kernels().finish_rest,
                y0,
                rh,
                x0,
                rw,
                albedo,
                pre_post,
                walks,
                base,
                scale,
                scaled,
                add,
                out,
            )

    def _finish(self, light, fy0, mode, on, ox0, owned, finish, out) -> None:
        """``finish_band`` of ``light``'s rows (frame rows from ``fy0``)."""
        backend.run_kernel(
            _kernels().finish_band,
            light, fy0, self._region[2], mode, on, ox0, owned, self.mask, self.thickness, self.ids_c,
            self.part_ids, self.ids is None, *finish, out,
        )  # fmt: skip

    def _stream_pyramid(self, transmit, p, q: _Part, flat) -> None:
        """Part ``p``'s reduced levels into ``flat`` (``spread_pyramid`` band by band, the light of
        the rows it reads computed for them; then ``blur_reduced``)."""
        if not np.any(q.levels[:, 0] > 0):
            return
        top_f = int(max(1, q.levels[:, 0].max()))
        wide, box = q.wide, q.box
        n_bands = -(-(int(wide[1]) - int(wide[0])) // top_f)
        step = max(1, SPREAD_BAND // top_f)
        rows = _Rows(self, transmit)
        light = np.empty((step * top_f, self._region[3] - self._region[2], 3), np.float32)
        on = np.empty((step * top_f, box[3] - box[2]), np.uint8)
        for ja in range(0, n_bands, step):
            jb = min(ja + step, n_bands)
            a = max(int(wide[0]) + ja * top_f, box[0])
            b = min(int(wide[0]) + jb * top_f, box[1])
            if a < b:
                rows.light(a, b, light[: b - a])
                self._on(p, q.part, a, b, on)
            else:
                a = 0
            backend.run_kernel(
                _spread_kernels().spread_pyramid,
                light,
                on,
                q.part,
                wide,
                q.levels,
                flat,
                ja,
                jb,
                a,
                a,
            )
        self._blur_levels(q, flat)

    def _stream_bands(self, transmit, p, q: _Part, flat, finish, finish_mode, owned, out) -> None:
        """Part ``p``'s bands (``_bands_of``), the light of the rows each reads computed once in a
        window that moves down with them, and each band's rows finished into ``out``
        (``finish_mode`` 0: all the region's pixels on them; 1: the part's)."""
        box = q.box
        rows = _Rows(self, transmit)
        bands = _bands(box, q.wide, q.radii, q.needed, q.n_full)
        reach = max((3 * int(q.radii[k - 1]) for k in range(1, q.n_full) if q.needed[k, 3]), default=0)
        cap = max(b1 - b0 for b0, b1 in bands) + reach
        light = np.empty((cap, self._region[3] - self._region[2], 3), np.float32)
        on = np.empty((cap, box[3] - box[2]), np.uint8)
        curvature = np.zeros((cap, rows.far_w), np.float32)
        held = [box[0], box[0]]  # region rows held: held[0]..held[1] - 1
        fy0, fx0 = self._region[0], rows.far_x0

        def band_light(b0, b1, reach_rows):
            lo, hi = held
            if reach_rows is None:
                self._finish(light[b0 - lo : b1 - lo], fy0 + b0, finish_mode, on[b0 - lo : b1 - lo], box[2], owned,
                             finish, out)  # fmt: skip
                return None
            need = min(b1 + reach_rows, box[1])
            if b0 > lo:  # rows above the band: no longer read
                keep = max(hi - b0, 0)
                light[:keep] = light[b0 - lo : b0 - lo + keep]
                on[:keep] = on[b0 - lo : b0 - lo + keep]
                curvature[:keep] = curvature[b0 - lo : b0 - lo + keep]
                lo, hi = b0, max(hi, b0)
            if hi < need:
                rows.light(hi, need, light[hi - lo : need - lo], curvature[hi - lo : need - lo])
                self._on(p, q.part, hi, need, on[hi - lo :])
                hi = need
            held[:] = [lo, hi]
            return light, lo, on, lo, (curvature, fy0 + lo, fx0)

        self._bands_of(q, p, light, 0, on, 0, None, flat, band_light)


class _Rows:
    """The transmitted light (before its spread) of the region's rows, asked for in ascending order:
    the far side's curvature (``_Curvature``), ``back_light_pixels`` and ``transmit_pixels`` on
    those rows only."""

    def __init__(self, back: CompiledBackLight, transmit):
        self.back = back
        self.transmit = transmit
        far = back.far
        self.curvature = None if far is None else _Curvature(back.mask, back.normal, back.position, far)
        self.far_x0 = 0 if far is None else far[2]
        self.far_w = 0 if far is None else far[3] - far[2]
        self.lit_rows = np.empty(0, bool)

    def _curvature(self, a, b, out) -> tuple[np.ndarray, int, int]:
        """The curvature of region rows ``a``..``b`` - 1 (zeros off the far side's box) into ``out``
        (or a new array), as (largest, cy0, cx0) for the kernels."""
        if self.curvature is None:
            return np.zeros((0, 0), np.float32), 0, 0
        if out is None:
            out = np.empty((b - a, self.far_w), np.float32)
        assert self.back.far is not None
        y0 = self.back._region[0]
        fy0, fy1 = self.back.far[0], self.back.far[1]
        fa, fb = max(y0 + a, fy0), min(y0 + b, fy1)
        out[: max(fa - y0 - a, 0)] = 0.0
        out[max(fb - y0 - a, 0) :] = 0.0
        if fa < fb:
            self.curvature.rows(fa - fy0, fb - fy0, out[fa - y0 - a : fb - y0 - a])
        return out, y0 + a, self.far_x0

    def light(self, a, b, out, curvature=None) -> None:
        """The light of region rows ``a``..``b`` - 1 into ``out`` (and their curvature into
        ``curvature`` when given)."""
        back = self.back
        largest, cy0, cx0 = self._curvature(a, b, curvature)
        if self.lit_rows.size < b - a:
            self.lit_rows = np.empty(b - a, bool)
        fy0 = back._region[0] + a
        back._irradiance(largest, cy0, cx0, fy0, out, self.lit_rows[: b - a])
        back._transmit(self.transmit, largest, cy0, cx0, fy0, out, out, False, np.empty((1, 1, 17)))

    def widths(self, a, b, part_rows) -> None:
        """``transmit_pixels``' rows of widths of region rows ``a``..``b`` - 1 into ``part_rows``,
        without their light (on no irradiance only the widths are computed)."""
        back = self.back
        largest, cy0, cx0 = self._curvature(a, b, None)
        e = np.zeros((b - a, back._region[3] - back._region[2], 3), np.float32)
        back._transmit(self.transmit, largest, cy0, cx0, back._region[0] + a, e, e, True, part_rows)
