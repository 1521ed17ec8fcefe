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
(``core.mapping.technique_params``) and a mask of the pixels whose Material Index is the
material's pass index. ``core.plan.plan`` decides beforehand, without computing anything,
which materials are computed and why others are left as they are; ``core.sequence.apply_file``
does the same for a passes file on disk.
"""

from __future__ import annotations

import numpy as np

from . import _arrays
from .exr import Passes
from .passes import THICKNESS
from .plan import Plan, _accepted, _index_map, plan
from .scene import SceneDescription
from .spec import Technique

ALBEDO_MODES = _arrays.ALBEDO_MODES

#: Name of the layers ``apply`` returns: ``SSSLab.<technique>.Image`` and ``.SSS``.
LAYER_PREFIX = "SSSLab"


def layer_names(technique: str) -> tuple[str, str]:
    """(image layer, SSS-term layer) names for ``technique``."""
    return f"{LAYER_PREFIX}.{technique}.Image", f"{LAYER_PREFIX}.{technique}.SSS"


def _finite(a: np.ndarray) -> np.ndarray:
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


def _clean(a: np.ndarray) -> np.ndarray:
    """A float32 copy with NaN and +-Inf replaced by 0 (no other value changes; nothing clamped)."""
    out = np.array(a, dtype=np.float32)
    finite = np.isfinite(out)
    if not finite.all():
        out[~finite] = 0.0
    return out


#: Inputs a technique gets from a pass it reads, as the keyword of its function (NaN and Inf
#: become 0 and leave the pixel as it is). The passes every scattering technique reads (Diffuse
#: Direct + Indirect, Diffuse Color, Depth) and Combined and Material Index are handled apart.
_PASS_KEYWORDS = {"Normal": "normal", "Position": "position", "Object Index": "object_id", THICKNESS: "thickness"}


def _inputs(spec: Technique, passes: Passes, scene: SceneDescription, albedo_mode: str):
    """(keyword inputs of ``spec``'s function but the mask and the material's parameters, the
    diffuse light Combined holds (albedo x (Direct + Indirect)) or None, per-pixel finiteness of
    the inputs)."""
    albedo_raw = passes["Diffuse Color"]
    albedo = _clean(albedo_raw)
    ok = _finite(albedo_raw)
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
        if name != "Object Index":  # an index pass is read as it is (Blender writes it finite)
            ok &= _finite(raw)
        if name == THICKNESS and raw.ndim == 3:
            raw = raw[..., 0]  # a value AOV: one channel
        inputs[keyword] = _clean(raw)
    original = None
    if spec.scatters:
        direct, indirect = passes["Diffuse Direct"], passes["Diffuse Indirect"]
        depth_raw = passes["Depth"]
        ok &= _finite(direct) & _finite(indirect) & _finite(depth_raw)
        diffuse = _clean(direct) + _clean(indirect)
        original = albedo * diffuse  # the diffuse light Combined holds on these pixels
        pre, tech_albedo = _arrays.split_albedo(albedo, albedo_mode)
        inputs["diffuse"] = diffuse if pre is None else pre * diffuse
        inputs["albedo"] = tech_albedo
        # Invalid depth becomes background (1e10), which gives and receives no light.
        inputs["depth"] = np.where(np.isfinite(depth_raw), depth_raw, np.float32(1e10)).astype(np.float32)
    return inputs, original, ok


def _call(func, kwargs: dict):
    accepted, var_kw = _accepted(func)
    if not var_kw:
        kwargs = {k: v for k, v in kwargs.items() if k in accepted}
    return func(**kwargs)


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
    p = prepared or plan(passes, scene, technique, albedo_mode=albedo_mode, mapping=mapping, **options)
    if not p.scattering:
        return {}
    spec = p.spec
    combined = passes["Combined"]
    rgb = combined[..., :3]
    image = np.array(combined, dtype=np.float32)
    sss = np.zeros(rgb.shape, dtype=np.float32)
    index = _index_map(passes)
    inputs, original, ok = _inputs(spec, passes, scene, albedo_mode)
    ok &= _finite(rgb)
    nonfinite = overflow = 0
    for mp in p.applied:
        mask = index == mp.material.index
        nonfinite += int((mask & ~ok).sum())
        mask &= ok
        # The material's pixels lie in its mask's bounding box: the compositing reads nothing else.
        box = _arrays.bounding_box(mask)
        if box is None:
            continue
        kwargs = dict(inputs)
        kwargs.update(mp.params)
        # A technique that takes the fitted gain applies it itself (the combined technique, to its
        # diffusion only); for the others it scales their result below.
        gain = None if "gain" in spec.keywords else kwargs.pop("gain", None)
        kwargs["mask"] = mask
        # Light near float32's limit can overflow in a technique's sums: counted below and said
        # (overflow_pixels), instead of NumPy's raw RuntimeWarning.
        with np.errstate(over="ignore", invalid="ignore"):
            out = np.asarray(_call(spec.function, kwargs), dtype=np.float32)
        if out.shape != rgb.shape:
            raise ValueError(f"{spec.name} returned shape {out.shape}; expected {rgb.shape}")
        out = out[box]
        if gain is not None:
            # The fitted per-channel energy (core/fit_params.py): on the material's light after the
            # technique (for STA, on the light it adds).
            out = out * np.asarray(gain, np.float32)
        m = mask[box]
        with np.errstate(over="ignore", invalid="ignore"):
            good = m & _finite(out)
        overflow += int(m.sum() - good.sum())
        if not spec.scatters:
            term = out
        else:
            term = out - original[box]
            if mp.unchanged_channels:
                term[..., list(mp.unchanged_channels)] = 0.0
        # Masked copies, not boolean indexing: the latter packs the pixels first (some 40 ms a
        # material at 1080p); the values written are the same float32 sums.
        where = good[..., None]
        with np.errstate(over="ignore", invalid="ignore"):
            np.copyto(image[box][..., :3], rgb[box] + term, where=where)
        np.copyto(sss[box], term, where=where)
    p.nonfinite_pixels = nonfinite
    p.overflow_pixels = overflow
    name_image, name_sss = layer_names(spec.name)
    return {name_image: image, name_sss: sss}
