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
from .plan import Plan, _accepted, _index_map, plan
from .scene import SceneDescription
from .techniques import get_technique

ALBEDO_MODES = _arrays.ALBEDO_MODES

#: Name of the layers ``apply`` returns: ``SSSLab.<technique>.Image`` and ``.SSS``.
LAYER_PREFIX = "SSSLab"


def layer_names(technique: str) -> tuple[str, str]:
    """(image layer, SSS-term layer) names for ``technique``."""
    return f"{LAYER_PREFIX}.{technique}.Image", f"{LAYER_PREFIX}.{technique}.SSS"


def _finite(a: np.ndarray) -> np.ndarray:
    """Per-pixel finiteness of an (H, W) or (H, W, C) array."""
    ok = np.isfinite(a)
    return ok.all(axis=-1) if a.ndim == 3 else ok


def _clean(a: np.ndarray) -> np.ndarray:
    """A float32 copy with NaN and +-Inf replaced by 0 (no other value changes; nothing clamped)."""
    out = np.array(a, dtype=np.float32)
    out[~np.isfinite(out)] = 0.0
    return out


def _call(func, kwargs: dict):
    accepted, var_kw = _accepted(func)
    if not var_kw:
        kwargs = {k: v for k, v in kwargs.items() if k in accepted}
    return func(**kwargs)


def apply(
    passes: Passes,
    scene: SceneDescription,
    technique: str,
    *,
    albedo_mode: str = "post",
    mapping=None,
    prepared: Plan | None = None,
    **options,
) -> dict[str, np.ndarray]:
    """Run ``technique`` on every scattering material and composite the result.

    Returns the new layers, float32, rows top to bottom:
    ``SSSLab.<technique>.Image`` (H, W, C) with C and the alpha of Combined, and
    ``SSSLab.<technique>.SSS`` (H, W, 3), the SSS term alone (scattered minus the original
    diffuse for SSSS and Burley, the added light for STA). Pixels of materials that do not
    scatter, are skipped by the plan, or have a NaN/Inf input keep Combined exactly (SSS 0).
    When no material scatters, returns {} (nothing to write).

    ``albedo_mode``: "post" applies the albedo after scattering (out = A * scatter(E));
    "pre-post" splits it, out = sqrt(A) * scatter(sqrt(A) * E), keeping half of the texture
    detail under the blur (Jimenez et al. 2015, the separable SSS demo's pre/post scatter
    option). STA does not scatter and ignores it. ``prepared`` is the result of ``plan`` for
    the same arguments, to avoid planning twice.
    """
    p = prepared or plan(passes, scene, technique, albedo_mode=albedo_mode, mapping=mapping, **options)
    if not p.scattering:
        return {}
    func = get_technique(technique)
    combined = passes["Combined"]
    rgb = combined[..., :3]
    image = np.array(combined, dtype=np.float32)
    sss = np.zeros(rgb.shape, dtype=np.float32)
    index = _index_map(passes)
    albedo_raw = passes["Diffuse Color"]
    albedo = _clean(albedo_raw)
    ok = _finite(rgb) & _finite(albedo_raw)
    inputs = {}
    if technique in ("sta", "combined"):
        thickness_raw = passes[scene.thickness_aov]
        normal_raw, position_raw = passes["Normal"], passes["Position"]
        ok &= _finite(thickness_raw) & _finite(normal_raw) & _finite(position_raw)
        inputs = {
            "albedo": albedo,
            "normal": _clean(normal_raw),
            "position": _clean(position_raw),
            "thickness": _clean(thickness_raw if thickness_raw.ndim == 2 else thickness_raw[..., 0]),
            "camera": scene.camera,
            "lights": scene.lights,
            "thickness_convention": scene.thickness_convention,
        }
    if technique != "sta":
        direct, indirect = passes["Diffuse Direct"], passes["Diffuse Indirect"]
        depth_raw = passes["Depth"]
        ok &= _finite(direct) & _finite(indirect) & _finite(depth_raw)
        diffuse = _clean(direct) + _clean(indirect)
        original = albedo * diffuse  # the diffuse light Combined holds on these pixels
        pre, tech_albedo = _arrays.split_albedo(albedo, albedo_mode)
        tech_diffuse = diffuse if pre is None else pre * diffuse
        inputs |= {
            "diffuse": tech_diffuse,
            "albedo": tech_albedo,
            # Invalid depth becomes background (1e10), which gives and receives no light.
            "depth": np.where(np.isfinite(depth_raw), depth_raw, np.float32(1e10)).astype(np.float32),
            "camera": scene.camera,
        }
        if technique in ("burley", "combined"):
            inputs["object_id"] = _clean(passes["Object Index"])
    nonfinite = 0
    for mp in p.applied:
        mask = index == mp.material.index
        nonfinite += int((mask & ~ok).sum())
        mask &= ok
        if not mask.any():
            continue
        kwargs = dict(inputs)
        kwargs.update(mp.params)
        # A technique that takes the fitted gain applies it itself (the combined technique, to its
        # diffusion only); for the others it scales their result below.
        gain = None if "gain" in _accepted(func)[0] else kwargs.pop("gain", None)
        kwargs["mask"] = mask
        out = np.asarray(_call(func, kwargs), dtype=np.float32)
        if out.shape != rgb.shape:
            raise ValueError(f"{technique} returned shape {out.shape}; expected {rgb.shape}")
        if gain is not None:
            # The fitted per-channel energy (core/fit_params.py): on the material's light after the
            # technique (for STA, on the light it adds).
            out = out * np.asarray(gain, np.float32)
        good = mask & _finite(out)
        nonfinite += int((mask & ~good).sum())
        if technique == "sta":
            term = out
        else:
            term = out - original
            if mp.unchanged_channels:
                term = term.copy()
                term[..., list(mp.unchanged_channels)] = 0.0
        image[..., :3][good] = rgb[good] + term[good]
        sss[good] = term[good]
    p.nonfinite_pixels = nonfinite
    name_image, name_sss = layer_names(technique)
    return {name_image: image, name_sss: sss}
