"""The combined technique's light from behind on the compiled backend (``core.compiled``).

``core.combined.back_light`` and ``BackLight.transmitted`` are the readable NumPy reference; here
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
(``core.backend``) every ``transmitted`` and ``add_to`` is compared with the reference's with a
bound of 0.

Without a medium (Burley's law) the reference's exponentials are NumPy's vectorized ones, which
a kernel does not reproduce to the bit: that case stays on the NumPy code, as do inputs whose
shapes the reference would reject (it then raises its own error).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import _arrays, backend
from .scene import Light
from .transmittance import (
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

_c = np.ascontiguousarray


def _spans_box(lo: np.ndarray, hi: np.ndarray) -> tuple[int, int, int, int] | None:
    """(first row, last row + 1, first column, last column + 1) of per-row spans [lo, hi)."""
    rows = np.flatnonzero(hi > lo)
    if not rows.size:
        return None
    return int(rows[0]), int(rows[-1]) + 1, int(lo[rows].min()), int(hi[rows].max())


def _camera_vector(camera) -> np.ndarray:
    """``core.compiled._view_vector``'s camera: (orthographic, position (3), -forward (3)) float32."""
    cam = np.zeros(7, np.float32)
    if camera is not None:
        cam[0] = 1.0 if camera.type == "ORTHO" else 0.0
        cam[1:4] = camera.position.astype(np.float32)
        cam[4:7] = (-camera.forward).astype(np.float32)
    return cam


def _largest_curvature(mask, normal, position, box) -> np.ndarray:
    """``core.energy.surface_curvature``'s largest curvature (radius 1) on ``box`` (rows y0..y1 - 1,
    columns x0..x1 - 1) of the far side's pixels (``mask`` with finite normal and position), as
    ``core.combined.far_side`` reads it: ``core.compiled.largest_pixels``, ``box_planes`` and
    ``largest_out``, the energy stage's kernels' operations without their frames of unit normals
    and mean curvature (equal to the bit; in check mode compared with ``surface_curvature``)."""
    from .energy import surface_curvature

    y0, y1, x0, x1 = box
    planes = np.empty((2, y1 - y0, x1 - x0), np.float64)
    backend.run_kernel("largest_pixels", normal, position, mask, y0, x0, planes)
    backend.run_kernel("box_planes", planes, 2, 1)
    out = np.empty((y1 - y0, x1 - x0), np.float32)
    backend.run_kernel("largest_out", planes, normal, position, mask, y0, x0, out)
    if backend.active() == "check":
        window = slice(y0, y1), slice(x0, x1)
        far = mask[window] & _arrays.finite_pixels(normal[window], position[window])
        with backend.use("numpy"):
            reference = surface_curvature(normal[window], position[window], far, radius_px=1)[1]
        backend.compare("largest curvature", reference, out, np.zeros(out.shape))
    return out


def compiled_back_light(t, distance, **a) -> CompiledBackLight | None:
    """``core.combined.back_light(**a)`` on the compiled backend (``t`` the thickness map as
    float32 (H, W), ``distance`` the bake's distance, both checked), or None where the NumPy code
    must run (no medium, or inputs whose shapes it rejects)."""
    from . import compiled as kernels
    from .energy import CHORD_CAP

    medium, camera = a["medium"], a["camera"]
    if medium is None:
        return None
    n = _arrays.image(a["normal"], "normal")
    shape = n.shape[:2]
    if t.shape != shape:
        return None
    p = _arrays.image(a["position"], "position")
    _arrays.same_size(shape, position=p)
    m = _arrays.mask_array(a["mask"], shape)
    z = None
    if a["depth"] is not None:
        z = _arrays.image(a["depth"], "depth", None)
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
        albedo = _arrays.image(a["albedo"], "albedo")
        _arrays.check_albedo_mode(a["albedo_mode"])
        _arrays.same_size(shape, albedo=albedo)
    lights = list(a["lights"])
    for light in lights:
        if not isinstance(light, Light):
            raise ValueError(f"lights: expected core.scene.Light entries, got {type(light).__name__}")
    as_thickness = a["thickness_convention"] == "thickness"
    mc, nc, pc, tc = _c(m), n, p, t
    spans = np.empty((shape[0], 4), np.int64)
    backend.run_kernel("back_light_spans", mc, nc, pc, tc, spans)
    far = _spans_box(spans[:, 0], spans[:, 1])
    region = _spans_box(spans[:, 2], spans[:, 3])
    largest = np.zeros((0, 0), np.float32)
    cy0 = cx0 = 0
    if camera is not None and far is not None:
        fy0, fy1, fx0, fx1 = far
        largest = _largest_curvature(mc, n, p, far)
        cy0, cx0 = fy0, fx0
    kmin = 2.0 / (CHORD_CAP * float(distance))
    walks = camera is not None and medium.walks
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
        largest=largest,
        curvature_origin=(cy0, cx0),
        cam=_camera_vector(camera),
        region=region,
        depth=z,
        ids=ids,
        albedo=albedo,
        pre_post=a["albedo_mode"] == "pre-post",
    )
    if region is None:
        return back
    y0, y1, x0, x1 = region
    e = np.empty((y1 - y0, x1 - x0, 3), np.float32)
    lit_rows = np.empty(y1 - y0, bool)
    table = kernels.light_table([light for light in lights if light.energy > 0])
    backend.run_kernel(
        "back_light_pixels", mc, nc, pc, tc, as_thickness, float(distance), kmin, walks, back.cam, largest, cy0, cx0,
        table, y0, x0, e, lit_rows,
    )  # fmt: skip
    back.e = e
    back.lit = np.array(lit_rows.any())
    if z is not None and camera is not None and back.lit:
        back.spread = True
        if ids is None:
            back.part_ids = np.zeros(1, np.int64)
        else:
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


#: Rows of a part the spread goes down at a time (``core.compiled.spread_band``): its level planes
#: and results are held for a band of rows, not for the part.
SPREAD_BAND = 128


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
    from .compiled import PART_STRIP

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
class CompiledBackLight:
    """``core.combined.BackLight`` on the compiled backend: the irradiance from behind on the
    region (``e``), the inputs the kernels read again per length (no frame is copied), and in
    check mode the reference's ``BackLight`` (``reference``)."""

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
    largest: np.ndarray
    curvature_origin: tuple[int, int]
    cam: np.ndarray
    region: tuple[int, int, int, int] | None
    depth: np.ndarray | None
    ids: np.ndarray | None
    albedo: np.ndarray | None
    pre_post: bool
    e: np.ndarray | None = None
    #: Whether a pixel is lit from behind (a 0-d array: ``lit.any()`` as on ``BackLight.lit``).
    lit: np.ndarray = field(default_factory=lambda: np.array(False))
    spread: bool = False
    part_ids: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    ids_c: np.ndarray = field(default_factory=lambda: np.zeros((1, 1), np.int64))
    reference: Any = None
    #: The medium's tables (the transmittance's columns, the lateral spread's), read at the first call.
    tables: dict = field(default_factory=dict)

    def transmitted(self, d_su, transmission_scale=1.0) -> np.ndarray:
        """``core.combined.BackLight.transmitted``."""
        out = np.zeros(self.shape + (3,), np.float32)
        self._into(out, d_su, transmission_scale, add=False, last=False)
        if self.reference is not None:
            reference = self.reference.transmitted(d_su, transmission_scale)
            backend.compare("light from behind", reference, out, np.zeros(out.shape))
        return out

    def add_to(self, out: np.ndarray, d_su, transmission_scale=1.0, *, last: bool = False) -> None:
        """``core.combined.BackLight.add_to``: ``out`` += the transmitted light, in place."""
        expected = None
        if self.reference is not None:
            expected = out + self.reference.transmitted(d_su, transmission_scale)
        self._into(out, d_su, transmission_scale, add=True, last=last)
        if expected is not None:
            backend.compare("light from behind (added)", expected, out, np.zeros(out.shape))

    def _into(self, out, d_su, transmission_scale, *, add: bool, last: bool) -> None:
        scale = _arrays.rgb_lengths(transmission_scale, "transmission_scale").astype(np.float32)
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
                columns = np.zeros((3, len(entries), TAUS.size), np.float64)
                for c in range(3):
                    for g, entry in enumerate(entries):
                        columns[c, g] = passage_column(alpha[c], entry)
                self.tables["columns"] = columns
            nodes = TAUS
            kind = 1 if skin else 0
        else:
            ell = _arrays.rgb_lengths(d_su, "transmission_d_su").astype(np.float64)
            grid = np.zeros(1, np.float64)
            columns = np.broadcast_to(disk_table()[0], (3, 1, DISK_U.size)).copy()
            nodes = DISK_U
            kind = 2
        spread_len = _arrays.rgb_lengths(d_su, "transmission_d_su").astype(np.float64)
        if self.region is not None and self.e is not None:
            light = self._light(kind, ell, grid, columns, nodes, spread_len, last)
        else:
            light = np.zeros((0, 0, 3), np.float32)
        y0, x0 = (0, 0) if self.region is None else self.region[::2]
        weight = self.albedo is not None
        albedo = self.albedo if weight else np.zeros((1, 1, 3), np.float32)
        base = np.asarray(medium.base_color, np.float32)
        backend.run_kernel(
            "finish_light", light, y0, x0, albedo, self.pre_post, walks, base, weight, scale,
            bool(np.any(scale != 1)), add, out,
        )  # fmt: skip

    def _light(self, kind, ell, grid, columns, nodes, spread_len, last) -> np.ndarray:
        """The transmitted light on the region after its spread, float32 (rows, columns, 3)."""
        from .combined import _box_radius, _full_levels, _pyramid_layout, _reduced_levels, _spread_levels

        assert self.region is not None and self.e is not None
        medium = self.medium
        y0, y1, x0, x1 = self.region
        e = self.e
        light = e if last else np.empty(e.shape, np.float32)
        n_parts = self.part_ids.size if self.spread else 0
        if self.spread and medium.walks:
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
        elif self.spread:
            m2 = disk_table()[1]
            counts = np.full(3, DISK_U.size, np.int64)
            values = np.broadcast_to(m2, (3, m2.size)).copy()
            spread_nodes = DISK_U
        else:
            counts = np.zeros(3, np.int64)
            values = np.zeros((3, 1), np.float64)
            spread_nodes = np.zeros(1, np.float64)
        part_rows = np.empty((y1 - y0 if self.spread else 1, max(n_parts, 1), 17), np.float64)
        view = self.camera is not None and medium.walks
        cy0, cx0 = self.curvature_origin
        ior2 = float(medium.ior) * float(medium.ior)
        camera = self.camera
        ortho = camera is not None and camera.type == "ORTHO"
        focal = np.float32(0.0 if camera is None else camera.ortho_px_per_unit if ortho else camera.focal_px)
        depth = self.depth if self.spread else np.zeros((1, 1), np.float32)
        widths = (kind, _c(spread_len), counts, spread_nodes, values)
        backend.run_kernel(
            "transmit_pixels", e, self.mask, self.normal, self.position, self.thickness, self.as_thickness,
            self.distance, self.kmin, self.largest, cy0, cx0, y0, x0, view, self.cam, kind, ior2, _c(ell), grid,
            columns, nodes, self.spread, *widths[1:], self.ids_c, self.part_ids, depth, ortho, focal, light, part_rows,
        )  # fmt: skip
        if not self.spread:
            return light
        h, w = self.shape
        one_part = self.ids is None
        assert self.depth is not None
        for p in range(n_parts):
            box = _spans_box(part_rows[:, p, 0].astype(np.int64), part_rows[:, p, 1].astype(np.int64))
            if box is None:
                continue
            fill = part_rows[:, p, 2:5].max(axis=0).astype(np.float32)
            part = np.array(box, np.int64)
            rows = _width_ranges(part_rows[box[0] : box[1], p], fill)
            least, most = rows[..., 0].min(axis=0), rows[..., 1].max(axis=0)
            top = float(most.max(initial=0.0))
            sigmas = _spread_levels(top)
            if len(sigmas) == 1:
                continue
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
            ph, pw = box[1] - box[0], box[3] - box[2]
            radii = np.array([_box_radius(sg) for sg in sigmas[1:]], np.int64)
            on = np.empty((ph, pw), np.uint8)
            backend.run_kernel(
                "part_pixels", self.mask, self.thickness, self.ids_c, self.part_ids, p, one_part, y0, x0, part, on
            )
            grid = np.asarray(sigmas, np.float64)
            needed = _needed_levels(grid, least, most)
            n_full = _full_levels(sigmas)
            # The reduced levels first, from the light before the bands below replace it.
            levels, size = _pyramid_layout(sigmas, wide, needed[:, 3])
            flat = np.empty(size, np.float32)
            for _ in _reduced_levels(light, on, part, wide, sigmas, levels, flat):
                pass
            state, at = _band_state(radii, needed, n_full, pw)
            row_levels = _row_levels(grid, rows)
            bands = _bands(box, wide, radii, needed, n_full)
            most_rows = max(b1 - b0 for b0, b1 in bands)
            band_planes = np.empty((4, most_rows, pw), np.float32)
            band_out = np.empty((most_rows, light.shape[1], 3), np.float32)
            band_sig = np.empty((most_rows, light.shape[1], 3), np.float32)
            for b0, b1 in bands:
                out = band_out[: b1 - b0]
                sig = band_sig[: b1 - b0]
                backend.run_kernel(
                    "band_sigma", self.mask, self.normal, self.position, self.thickness, self.as_thickness,
                    self.distance, self.kmin, self.largest, cy0, cx0, y0, x0, *widths, self.ids_c, self.part_ids, p,
                    one_part, self.depth, ortho, focal, fill, part, b0, b1, sig,
                )  # fmt: skip
                backend.run_kernel(
                    "spread_band", light, sig, on, part, wide, grid, n_full, radii, needed, row_levels, b0, b1,
                    state, at, band_planes, out,
                )  # fmt: skip
                # The band's rows as one part of their own, in the band's coordinates.
                band = np.array([0, b1 - b0, box[2], box[3]], np.int64)
                band_box = np.array([wide[0] - b0, wide[1] - b0, wide[2], wide[3]], np.int64)
                band_on = on[b0 - box[0] : b1 - box[0]]
                if n_full < len(sigmas):
                    backend.run_kernel(
                        "spread_reduced_part", light[b0:b1], sig, band_on, band, band_box, grid, n_full,
                        flat, levels, out,
                    )  # fmt: skip
                # Nothing reads these rows of the light again: the next bands' running sums have
                # passed them, and the reduced levels are made.
                backend.run_kernel("part_results", light[b0:b1], band_on, band, out)
        return light
