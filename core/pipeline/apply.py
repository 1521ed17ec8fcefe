"""Apply a technique to rendered passes: plan, compute, composite. No Blender needed.

The passes come from a render with the SSS materials rendered as plain diffuse (Subsurface
Weight 0, docs/references.md §7), so their diffuse light is in the Diffuse passes:
Combined = ... + Diffuse Color x (Diffuse Direct + Diffuse Indirect) + ... (the Diffuse
Direct/Indirect passes exclude the BSDF colour, docs/references.md §2). Rebuilding:

- SSSS and Burley scatter the diffuse light; on the pixels of a scattering material the image
  becomes Combined - albedo x (Direct + Indirect) + scattered, where ``scattered`` is the
  technique's albedo-applied result. Every other pixel is Combined, bit for bit.
- STA adds back-lit translucency: Combined + the STA term on the material's pixels.

Each technique gets one call per scattering material with that material's parameters
(``core.pipeline.mapping.technique_params``) and a mask of the pixels whose Material Index is the
material's pass index. ``core.pipeline.plan.plan`` decides beforehand, without computing anything,
which materials are computed and why others are left as they are; ``core.pipeline.sequence.apply_file``
does the same for a passes file on disk.

A technique with a composite route (``Technique.composite``: STA's) runs on the compiled backend
as one kernel per material that reads the passes as they are, finds the material's pixels and
composites into the layers itself, without the cleaned copies, NaN scans and masks of the
generic route; in check mode both routes run and must give the same bits. Materials it does not
take (zones of d, a Subsurface Weight per pixel, passes of another layout) take the generic route.
"""

from __future__ import annotations

import numpy as np

from ..base import arrays
from ..compute import backend
from ..scene.exr import Passes
from ..scene.inputs import weight_map
from ..scene.passes import THICKNESS
from ..scene.scene import SceneDescription
from ..techniques.spec import Technique
from .call import accepted_keywords, call_technique
from .plan import Plan, index_map, plan, plan_and_masks


def _kernels():
    """This package's compiled kernels (``_kernels.py``), loaded on first use."""
    return backend.kernels(__package__)


__all__ = [
    "ALBEDO_MODES",
    "LAYER_PREFIX",
    "apply",
    "bits_equal",
    "clean",
    "finite",
    "layer_names",
    "plan",
    "technique_inputs",
]

ALBEDO_MODES = arrays.ALBEDO_MODES

#: Name of the layers ``apply`` returns: ``SSSLab.<technique>.Image`` and ``.SSS``.
LAYER_PREFIX = "SSSLab"


def layer_names(technique: str) -> tuple[str, str]:
    """(image layer, SSS-term layer) names for ``technique``."""
    return f"{LAYER_PREFIX}.{technique}.Image", f"{LAYER_PREFIX}.{technique}.SSS"


def finite(a: np.ndarray) -> np.ndarray:
    """Per-pixel finiteness of an (H, W) or (H, W, C) array."""
    ok = np.isfinite(a)
    if a.ndim == 2:
        return ok
    if ok.all():  # the usual case, found in one pass: a reduction over the short last axis is slow
        return np.ones(a.shape[:2], bool)
    out = ok[..., 0].copy()
    for c in range(1, a.shape[2]):
        out &= ok[..., c]
    return out


def clean(a: np.ndarray) -> np.ndarray:
    """A float32 copy with NaN and +-Inf replaced by 0 (no other value changes; nothing clamped)."""
    out = np.array(a, dtype=np.float32)
    ok = np.isfinite(out)
    if not ok.all():
        out[~ok] = 0.0
    return out


def bits_equal(name: str, expected: np.ndarray, got: np.ndarray) -> None:
    if expected.shape != got.shape or expected.tobytes() != got.tobytes():
        raise backend.BackendMismatch(f"{name}: the compiled result differs from the NumPy code's bits")


def _read(raw: np.ndarray, first_channel: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """(``raw`` as a technique reads it: a float32 copy with NaN and +-Inf replaced by 0;
    per-pixel finiteness of ``raw``, or None when every value is finite). One scan finds the
    usual pass without NaN or Inf, which is copied as it is. ``first_channel``: the technique
    reads channel 0 alone (a value AOV stored with three); the finiteness covers every channel.

    The copy stays: the compiled kernels take their inputs as they are, and a read-only view
    would be a new argument type for Numba, compiled again for every kernel on a cold cache."""
    if raw.dtype == np.float32 and arrays.all_finite(raw):
        return np.array(raw[..., 0] if first_channel else raw, dtype=np.float32), None
    ok = finite(raw)
    return clean(raw[..., 0] if first_channel else raw), ok


def _both(ok: np.ndarray | None, other: np.ndarray | None) -> np.ndarray | None:
    """The pixels finite in both (None: every pixel)."""
    if ok is None:
        return other
    if other is not None:
        ok &= other
    return ok


#: Inputs a technique gets from a pass it reads, as the keyword of its function (NaN and Inf
#: become 0 and leave the pixel as it is). The passes every scattering technique reads (Diffuse
#: Direct + Indirect, Diffuse Color, Depth) and Combined and Material Index are handled apart.
_PASS_KEYWORDS = {"Normal": "normal", "Position": "position", "Object Index": "object_id", THICKNESS: "thickness"}


def technique_inputs(spec: Technique, passes: Passes, scene: SceneDescription, albedo_mode: str):
    """(keyword inputs of ``spec``'s function but the mask and the material's parameters; the
    diffuse light Combined holds (albedo x (Direct + Indirect)) or None; per-pixel finiteness of
    the inputs): ``_gather_inputs`` with whole frames, as ``core.study.fit`` reads them."""
    inputs, parts, ok = _gather_inputs(spec, passes, scene, albedo_mode)
    original = None if parts is None else parts[0] * parts[1]
    return inputs, original, np.ones(passes.shape, bool) if ok is None else ok


def _gather_inputs(spec: Technique, passes: Passes, scene: SceneDescription, albedo_mode: str):
    """(keyword inputs of ``spec``'s function but the mask and the material's parameters;
    (albedo, Direct + Indirect), whose product is the diffuse light Combined holds,
    or None; per-pixel finiteness of the inputs, None when every pixel is finite)."""
    albedo, ok = _read(passes["Diffuse Color"])
    inputs: dict = {
        "albedo": albedo,
        "camera": scene.camera,
        "lights": scene.lights,
        "thickness_convention": scene.thickness_convention,
    }
    names = [n for n in spec.passes]
    names += [n for n in spec.optional_passes if (scene.thickness_aov if n == THICKNESS else n) in passes.names]
    for name in names:
        keyword = _PASS_KEYWORDS.get(name)
        if keyword is None:
            continue
        raw = passes[scene.thickness_aov if name == THICKNESS else name]
        # A value AOV (thickness) stored with three channels is read from its first.
        inputs[keyword], ok_pass = _read(raw, first_channel=name == THICKNESS and raw.ndim == 3)
        if name != "Object Index":  # an index pass is read as it is (Blender writes it finite)
            ok = _both(ok, ok_pass)
    original = None
    if spec.scatters:
        direct, indirect = passes["Diffuse Direct"], passes["Diffuse Indirect"]
        ok_direct = ok_indirect = None
        if not all(a.dtype == np.float32 and arrays.all_finite(a) for a in (direct, indirect)):
            direct, ok_direct = _read(direct)
            indirect, ok_indirect = _read(indirect)
        depth = passes["Depth"]
        ok_depth = None
        if depth.dtype != np.float32 or not arrays.all_finite(depth):
            ok_depth = finite(depth)
            # Invalid depth becomes background (1e10), which gives and receives no light.
            depth = np.where(np.isfinite(depth), depth, np.float32(1e10)).astype(np.float32)
        ok = _both(_both(_both(ok, ok_direct), ok_indirect), ok_depth)
        diffuse = direct + indirect  # a new array: the passes are only read
        original = albedo, diffuse  # their product is the diffuse light Combined holds on these pixels
        pre, tech_albedo = arrays.split_albedo(albedo, albedo_mode)
        inputs["diffuse"] = diffuse if pre is None else pre * diffuse
        inputs["albedo"] = tech_albedo
        inputs["depth"] = depth if ok_depth is not None else np.array(depth, dtype=np.float32)
    return inputs, original, ok


def _composite(image, sss, out, gain, original, mask, unchanged) -> tuple[int, int]:
    """Write the technique's result ``out`` (H, W, 3) on the pixels of ``mask`` into the layers:
    ``sss`` the SSS term (``out`` times the fitted ``gain``, minus the light Combined held,
    ``original``'s albedo x diffuse light, for a technique that scatters; 0 in the channels
    ``unchanged``), ``image`` Combined plus that term. A pixel whose result is not finite (light
    near float32's limit overflowing in the technique's sums) is left as it was; a channel that
    the term would turn from non-negative to negative light is set to 0 (the passes' diffuse light
    exceeded Combined there: passes that disagree, or sums near float32's limit). Returns how
    many pixels of each: (overflowed, clamped). One compiled pass (``core.pipeline._kernels.composite``)
    where apply's kernels run, compared with the NumPy code (``_composite_numpy``) to the bit in
    check mode."""
    g = np.ones(3, np.float32) if gain is None else np.asarray(gain, np.float32)
    if backend.active() == "numpy" or g.shape not in ((), (3,)):
        return _composite_numpy(image, sss, out, gain, original, mask, unchanged)
    expected: tuple[np.ndarray, np.ndarray, tuple[int, int]] | None = None
    if backend.active() == "check":
        ref_image, ref_sss = image.copy(), sss.copy()
        expected = ref_image, ref_sss, _composite_numpy(ref_image, ref_sss, out, gain, original, mask, unchanged)
    c = np.ascontiguousarray
    result = out if out.flags.c_contiguous and out.flags.writeable and out.flags.aligned else np.array(out)
    held = original is not None
    albedo, diffuse = (c(original[0]), c(original[1])) if held else (result, result)
    zeroed = np.zeros(3, bool)
    if held:  # as the NumPy code: a technique that adds light keeps every channel of its result
        zeroed[list(unchanged)] = True
    bad = np.empty(mask.shape[0], np.int64)
    negative = np.empty(mask.shape[0], np.int64)
    gains = np.array(np.broadcast_to(g, (3,)))
    backend.run_kernel(
        _kernels().composite, result, gains, albedo, diffuse, held, zeroed, c(mask), image, sss, bad, negative
    )
    counts = int(bad.sum()), int(negative.sum())
    if expected is not None:
        bits_equal("composite (image)", expected[0], image)
        bits_equal("composite (SSS)", expected[1], sss)
        if counts != expected[2]:
            raise backend.BackendMismatch(
                f"composite: {counts} pixels overflowed and clamped, the NumPy code found {expected[2]}"
            )
    return counts


def _composite_numpy(image, sss, out, gain, original, mask, unchanged) -> tuple[int, int]:
    """``_composite`` in NumPy, on the mask's bounding box."""
    box = arrays.bounding_box(mask)
    if box is None:
        return 0, 0
    # The diffuse light Combined holds there.
    held = None if original is None else original[0][box] * original[1][box]
    out = out[box]
    if gain is not None:
        # The fitted per-channel energy (core/pipeline/fit_params.py): on the material's light after the
        # technique (for STA, on the light it adds).
        out = out * np.asarray(gain, np.float32)
    m = mask[box]
    overflow = 0
    if arrays.all_finite(out):
        good = m
    else:
        with np.errstate(over="ignore", invalid="ignore"):
            good = m & finite(out)
        overflow = int(np.count_nonzero(m) - np.count_nonzero(good))
    if held is None:
        term = out
    else:
        term = np.subtract(out, held, out=held)  # out - held, in held's array
        if unchanged:
            term[..., list(unchanged)] = 0.0
    # Masked copies, not boolean indexing: the latter packs the pixels first (some 40 ms a
    # material at 1080p); the values written are the same float32 sums. The SSS layer's copy
    # gets the mask for every channel (a mask broadcast over the channels is several times
    # slower); Combined's RGB is a strided view of RGBA, so the image is written one channel
    # at a time: over (rows, channels) NumPy's loops would run three values long.
    where = np.repeat(good[..., None], 3, axis=2)
    sss_box, image_box = sss[box], image[box]
    np.copyto(sss_box, term, where=where)
    total = np.empty(good.shape, np.float32)
    clamped = np.zeros(good.shape, bool)
    for c in range(3):
        with np.errstate(over="ignore", invalid="ignore"):
            np.add(image_box[..., c], sss_box[..., c], out=total)  # Combined + term where good
        # Never negative light where Combined had none: the channel goes to 0, its term to -Combined.
        below = good & (total < 0) & (image_box[..., c] >= 0)
        if below.any():
            clamped |= below
            np.copyto(sss_box[..., c], np.negative(image_box[..., c]), where=below)
            total[below] = 0.0
        np.copyto(image_box[..., c], total, where=good)
    return overflow, int(np.count_nonzero(clamped))


def _weighted(out, gain, original, mask, weight) -> tuple[np.ndarray, None]:
    """``out`` as Cycles mixes it at Subsurface Weight ``weight`` (a number, or per pixel (H, W)):
    the Principled BSDF is (1 - w) diffuse + w subsurface at the pixel the camera sees
    (docs/references.md §2), so a technique that scatters gives the diffuse light Combined holds
    plus ``w`` times its change, one that adds light ``w`` times its light. The fitted ``gain`` is
    applied first (to the technique's light, as ``_composite`` would); returns (the mixed result,
    None for the gain). Only the mask's bounding box is computed."""
    out = np.array(out, dtype=np.float32)
    box = arrays.bounding_box(mask)
    if box is None:
        return out, None
    part = out[box]
    if gain is not None:
        part *= np.asarray(gain, np.float32)
    w = np.float32(weight) if np.ndim(weight) == 0 else np.asarray(weight, np.float32)[box][..., None]
    if original is None:
        part *= w
    else:
        held = original[0][box] * original[1][box]
        part -= held
        part *= w
        part += held
    return out, None


def _generic(spec, passes, mp, mask, inputs, original, ok, image, sss, shape) -> tuple[int, int, int]:
    """One material on the generic route: ``spec``'s function on the pixels of ``mask`` whose
    inputs are finite (``ok``, None: all), its result composited into ``image`` and ``sss``.
    Returns (pixels of the mask with an input that is not finite, pixels whose result overflowed,
    pixels clamped to no negative light)."""
    nonfinite = overflow = negative = 0
    if ok is not None:
        within = mask & ok
        left = int(np.count_nonzero(within))
        nonfinite = int(np.count_nonzero(mask)) - left
        if not left:
            return nonfinite, 0, 0
        mask = within
    # Cycles mixes diffuse and subsurface by the Subsurface Weight, per pixel where it is linked.
    weight: np.ndarray | float | None = weight_map(mp.material, passes, mask)
    if weight is None and mp.material.subsurface_weight < 1.0:
        weight = mp.material.subsurface_weight
    # One run with the material's parameters, or one per zone of its d (core.pipeline.zones),
    # each gathering from the whole material and kept on the zone's pixels.
    for pixels, params in mp.zones or [(None, mp.params)]:
        kwargs = dict(inputs)
        kwargs.update(params)
        # A technique that takes the fitted gain applies it itself (the combined technique, to
        # its diffusion only); for the others it scales their result below.
        gain = None if "gain" in spec.keywords else kwargs.pop("gain", None)
        kwargs["mask"] = mask
        # Light near float32's limit can overflow in a technique's sums: counted below and said
        # (overflow_pixels), instead of NumPy's raw RuntimeWarning.
        with np.errstate(over="ignore", invalid="ignore"):
            out = np.asarray(call_technique(spec, **kwargs), dtype=np.float32)
        if out.shape != shape:
            raise ValueError(f"{spec.name} returned shape {out.shape}; expected {shape}")
        keep = mask if pixels is None else mask & pixels
        if weight is not None:
            out, gain = _weighted(out, gain, original, keep, weight)
        # The techniques only read their inputs: the diffuse light Combined holds on the
        # material (albedo x (Direct + Indirect)) is what it was before the technique ran.
        over, below = _composite(image, sss, out, gain, original, keep, mp.unchanged_channels)
        overflow += over
        negative += below
    return nonfinite, overflow, negative


def _routed(spec, mp, passes, scene, image, sss, generic, mask) -> tuple[int, int, int] | None:
    """One material on its technique's compiled route (``Technique.composite``: the technique and
    the compositing in one pass over the passes as they are), or None where the route does not
    apply. In check mode the generic route (``generic(mp, mask)``; ``mask`` the plan's pixels of
    the material, None: found here) runs too, into ``image`` and ``sss``, and the route, into
    copies of them, must give the same bits and counts (``BackendMismatch`` otherwise)."""
    params = dict(mp.params)
    gain = None if "gain" in spec.keywords else params.pop("gain", None)
    accepted, var_kw = accepted_keywords(spec.function)
    if not var_kw:
        params = {k: v for k, v in params.items() if k in accepted}
    weight = mp.material.subsurface_weight if mp.material.subsurface_weight < 1.0 else None
    index = mp.material.index
    if backend.active() != "check":
        return spec.composite(passes, scene, index, image, sss, gain, weight, params)
    routed_image, routed_sss = image.copy(), sss.copy()
    got = spec.composite(passes, scene, index, routed_image, routed_sss, gain, weight, params)
    if got is None:
        return None
    if mask is None:
        mask = index_map(passes) == index
    expected = generic(mp, mask) if mask.any() else (0, 0, 0)
    bits_equal(f"{spec.name}'s route (image)", image, routed_image)
    bits_equal(f"{spec.name}'s route (SSS)", sss, routed_sss)
    if got != expected:
        raise backend.BackendMismatch(
            f"{spec.name}'s route: (not finite, overflowed, clamped) pixels {got}, the generic route's {expected}"
        )
    return got


def apply(
    passes: Passes,
    scene: SceneDescription,
    technique: str | Technique,
    *,
    albedo_mode: str = "post",
    mapping=None,
    prepared: Plan | None = None,
    **options,
) -> dict[str, np.ndarray]:
    """Run ``technique`` on every scattering material and composite the result.

    Returns the new layers, float32, rows top to bottom:
    ``SSSLab.<technique>.Image`` (H, W, C) with C and the alpha of Combined, and
    ``SSSLab.<technique>.SSS`` (H, W, 3), the SSS term alone (for a technique that scatters, its
    result minus the original diffuse light; for one that only adds light, its result). Pixels of materials that do not
    scatter, are skipped by the plan, or have a NaN/Inf input keep Combined exactly (SSS 0).
    When no material scatters, returns {} (nothing to write).

    ``albedo_mode``: "post" applies the albedo after scattering (out = A * scatter(E));
    "pre-post" splits it, out = sqrt(A) * scatter(sqrt(A) * E), keeping half of the texture
    detail under the blur (Jimenez et al. 2015, the separable SSS demo's pre/post scatter
    option); a technique that does not scatter ignores it. ``technique``: a registered name or a
    ``Technique`` spec. ``prepared`` is the result of ``plan`` for
    the same arguments, to avoid planning twice.
    """
    if prepared is None:
        p, index, masks = plan_and_masks(passes, scene, technique, albedo_mode, mapping, options)
    else:
        # The pixels its plan found on these passes, if it was made on them (else found below).
        p, index, masks = prepared, None, prepared.planned_masks(passes)
    if not p.scattering:
        return {}
    spec = p.spec
    combined = passes["Combined"]
    rgb = combined[..., :3]
    image = np.array(combined, dtype=np.float32)
    sss = np.zeros(rgb.shape, dtype=np.float32)
    gathered: list = []  # the generic route's inputs, read once when a material takes it

    def generic(mp, mask) -> tuple[int, int, int]:
        if not gathered:
            inputs, original, ok = _gather_inputs(spec, passes, scene, albedo_mode)
            if not arrays.all_finite(combined):
                ok = _both(ok, finite(rgb))
            gathered.append((inputs, original, ok))
        inputs, original, ok = gathered[0]
        return _generic(spec, passes, mp, mask, inputs, original, ok, image, sss, rgb.shape)

    nonfinite = overflow = negative = 0
    for mp in p.applied:
        counts = None
        if spec.composite is not None and not mp.zones and "subsurface_weight" not in mp.material.per_pixel:
            counts = _routed(spec, mp, passes, scene, image, sss, generic, masks.get(mp.material.index))
        if counts is None:
            # The plan's pixels of the material (it found some), or the Material Index map's.
            mask = masks.get(mp.material.index)
            if mask is None:
                index = index_map(passes) if index is None else index
                mask = index == mp.material.index
                if not mask.any():
                    continue
            counts = generic(mp, mask)
        nonfinite += counts[0]
        overflow += counts[1]
        negative += counts[2]
    p.nonfinite_pixels = nonfinite
    p.overflow_pixels = overflow
    p.negative_pixels = negative
    name_image, name_sss = layer_names(spec.name)
    return {name_image: image, name_sss: sss}
