"""A Cycles reference spread over farm tasks by seed, merged into one (NumPy only, no Blender).

A reference of N × S samples is rendered as N tasks of S samples with N different seeds (each an
independent Monte Carlo estimate of the same image) and merged here:

- the merged image is the sample-count-weighted mean of the linear images,
  ``sum(n_i I_i) / sum(n_i)``: an estimate with ``sum(n_i)`` samples (Cycles' pixel value is the
  mean of its samples, so a part of n samples carries weight n);
- the parts are split into two halves A and B of (nearly) equal sample counts; the noise floor
  comes from the two halves, so that no extra render is needed.

Noise floor. The comparison's noise floor is the metric between the reference and a second,
independent reference of the same sample count (``docs/references.md §8``). For unbiased
estimates with per-sample variance s² per pixel, the difference of two independent n-sample
references has variance 2 s²/n, and the difference of the halves (n_A + n_B = n samples) has
variance s²/n_A + s²/n_B. The root-mean-square metrics of the halves are therefore scaled by
``sqrt(2 n_A n_B) / n`` (1/√2 for equal halves) to read on the same scale as the two-seed noise
floor. SSIM has no such scaling and is left out of the halves' noise floor.

Seeds must differ between parts: two renders with the same seed are the same noise, not more
samples.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from ..base.errors import InputError
from ..base.jsonfile import read_json
from ..scene import exr
from . import metrics

#: Layer names of a merged reference file: the merged image as a normal render's Combined pass
#: (so ``exr.read_passes`` reads it like any reference), and the two halves.
MERGED_LAYER = "ViewLayer.Combined"
HALF_LAYERS = ("SSSLab.HalfA.Combined", "SSSLab.HalfB.Combined")

#: File name of one part: the seed decides it, so that a re-queued task writes the same file.
PART_PATTERN = "reference_seed_{seed:05d}.exr"

#: The most samples one Cycles render takes (the hard maximum of its Samples setting): a merged
#: reference claiming more than this per part did not come from ``sss_lab reference``.
CYCLES_MAX_SAMPLES = 1 << 24


@dataclass(frozen=True)
class ReferencePart:
    """One task's render: a linear (H, W, C) float image of ``samples`` samples with ``seed``."""

    image: np.ndarray
    samples: int
    seed: int
    source: str = ""


@dataclass(frozen=True)
class MergedReference:
    """The merged image (float32, (H, W, C)), its total samples, the seeds, and the halves;
    ``part_samples``: each part's samples, in the order of ``seeds`` (None when not recorded)."""

    image: np.ndarray
    samples: int
    seeds: tuple[int, ...]
    halves: tuple[np.ndarray, np.ndarray] | None
    half_samples: tuple[int, int] | None
    half_seeds: tuple[tuple[int, ...], tuple[int, ...]] | None
    part_samples: tuple[int, ...] | None = None


def part_path(folder: str, seed: int) -> str:
    """The file one part with ``seed`` is written to in ``folder``."""
    return os.path.join(folder, PART_PATTERN.format(seed=seed))


def _check_parts(parts: Sequence[ReferencePart]) -> None:
    if not parts:
        raise InputError("reference parts: expected at least one part, got none")
    shape = None
    seen: dict[int, str] = {}
    for p in parts:
        name = p.source or f"seed {p.seed}"
        if not isinstance(p.samples, int) or isinstance(p.samples, bool) or p.samples < 1:
            raise InputError(f"{name}: samples: expected an integer >= 1, got {p.samples!r}")
        if not isinstance(p.seed, int) or isinstance(p.seed, bool) or p.seed < 0:
            raise InputError(f"{name}: seed: expected an integer >= 0, got {p.seed!r}")
        image = np.asarray(p.image)
        if image.ndim != 3 or image.shape[2] < 3:
            raise InputError(f"{name}: expected an (H, W, 3 or 4) image, got shape {image.shape}")
        if shape is None:
            shape = image.shape
        elif image.shape != shape:
            raise InputError(f"{name}: image shape {image.shape} differs from the other parts' {shape}")
        if p.seed in seen:
            raise InputError(
                f"{name} and {seen[p.seed]} have the same seed {p.seed}: the same noise twice is not more samples; "
                "render every part with its own seed"
            )
        seen[p.seed] = name


def split_halves(parts: Sequence[ReferencePart]) -> tuple[list[ReferencePart], list[ReferencePart]]:
    """Two groups of parts whose sample counts are as equal as a greedy split makes them.

    Parts are taken largest first (ties by seed) and each goes to the group with fewer samples
    so far, so that equal parts alternate: N parts of S samples give ⌈N/2⌉ and ⌊N/2⌋ parts.
    """
    a: list[ReferencePart] = []
    b: list[ReferencePart] = []
    for p in sorted(parts, key=lambda p: (-p.samples, p.seed)):
        (a if sum(q.samples for q in a) <= sum(q.samples for q in b) else b).append(p)
    return a, b


def _weighted_mean(parts: Sequence[ReferencePart]) -> np.ndarray:
    total = sum(p.samples for p in parts)
    acc = np.zeros(np.shape(parts[0].image), dtype=np.float64)
    for p in parts:
        acc += np.asarray(p.image, dtype=np.float64) * p.samples
    return (acc / total).astype(np.float32)


def merge_parts(parts: Iterable[ReferencePart]) -> MergedReference:
    """Merge parts rendered with different seeds into one reference (module docstring).

    Non-finite pixels stay non-finite in the merge (a NaN in one part is a NaN in the result,
    where the metrics leave it out and count it), never silently averaged away.
    """
    parts = list(parts)
    _check_parts(parts)
    image = _weighted_mean(parts)
    halves = half_samples = half_seeds = None
    if len(parts) >= 2:
        a, b = split_halves(parts)
        halves = (_weighted_mean(a), _weighted_mean(b))
        half_samples = (sum(p.samples for p in a), sum(p.samples for p in b))
        half_seeds = (tuple(sorted(p.seed for p in a)), tuple(sorted(p.seed for p in b)))
    by_seed = sorted(parts, key=lambda p: p.seed)
    return MergedReference(
        image=image,
        samples=sum(p.samples for p in parts),
        seeds=tuple(p.seed for p in by_seed),
        halves=halves,
        half_samples=half_samples,
        half_seeds=half_seeds,
        part_samples=tuple(p.samples for p in by_seed),
    )


def halves_scale(half_samples: tuple[int, int]) -> float:
    """The factor ``sqrt(2 n_A n_B) / n`` that puts the halves' RMSE on the two-seed noise floor's
    scale (module docstring)."""
    na, nb = half_samples
    return math.sqrt(2.0 * na * nb) / (na + nb)


def noise_floor(merged: MergedReference, mask: np.ndarray | None = None, *, box: int = 1) -> dict | None:
    """The noise floor of ``merged`` from its halves, as ``metrics.compare_images`` reports it for
    a second seed (rmse and rel_rmse scaled by ``halves_scale``; ssim None); None for one part."""
    if merged.halves is None or merged.half_samples is None:
        return None
    a, b = merged.halves
    m = metrics.compare_images(a, b, mask, box=box)
    k = halves_scale(merged.half_samples)
    out = dict(m)
    out["rmse"] = None if m["rmse"] is None else m["rmse"] * k
    out["rel_rmse"] = None if m["rel_rmse"] is None else m["rel_rmse"] * k
    out["ssim"] = None
    out["halves"] = {"samples": list(merged.half_samples), "seeds": [list(s) for s in merged.half_seeds or ()]}
    out["halves_rel_rmse"] = m["rel_rmse"]
    out["scale"] = k
    out["definition"] = (
        "metric between the two halves of the merged reference, rmse scaled by sqrt(2 nA nB)/n to the scale of "
        "two independent references of n samples"
    )
    return out


# --- Files ----------------------------------------------------------------------------------------


def sidecar(path: str) -> str:
    """The JSON written beside a part or a merged reference."""
    return os.path.splitext(path)[0] + ".json"


def _count(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 1


def _seed(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


def _pair(v) -> bool:
    return isinstance(v, list) and len(v) == 2 and all(_count(x) for x in v)


#: The fields a part's or a merged reference's JSON may hold, and what each must be; a field
#: absent is not checked (older files), one present with another type is refused.
_META_FIELDS: dict = {
    "samples": ("an integer >= 1", _count),
    "seed": ("an integer >= 0", _seed),
    "seeds": ("a list of integers >= 0", lambda v: isinstance(v, list) and all(_seed(x) for x in v)),
    "part_samples": (
        "null or a list of integers >= 1",
        lambda v: v is None or (isinstance(v, list) and all(_count(x) for x in v)),
    ),
    "half_samples": (
        "null or two integers >= 1",
        lambda v: v is None or (isinstance(v, list) and len(v) == 2 and all(_count(x) for x in v)),
    ),
    "half_seeds": (
        "null or two lists of integers >= 0",
        lambda v: (
            v is None
            or (
                isinstance(v, list) and len(v) == 2 and all(isinstance(s, list) and all(_seed(x) for x in s) for s in v)
            )
        ),
    ),
    "frame": ("an integer", lambda v: isinstance(v, int) and not isinstance(v, bool)),
    "fingerprint": ("a string", lambda v: isinstance(v, str)),
    "resolution": (
        "two integers >= 1 (width, height)",
        lambda v: isinstance(v, list) and len(v) == 2 and all(_count(x) for x in v),
    ),
    "seconds": (
        "a finite number >= 0",
        lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0,
    ),
}


def read_meta(meta_path: str, required: Sequence[str] = ()) -> dict:
    """The JSON beside a reference part or a merged reference, checked field by field as a scene
    description is (``_META_FIELDS``): InputError naming the file, the field and what it must be
    for a file that is not JSON, not an object, lacks a ``required`` field or holds a wrong value."""
    try:
        meta = read_json(meta_path, "the JSON beside a reference")
    except InputError:
        raise
    except (OSError, ValueError) as exc:
        raise InputError(f"{meta_path}: not readable JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise InputError(f"{meta_path}: expected a JSON object, got {type(meta).__name__}")
    missing = [k for k in required if k not in meta]
    if missing:
        raise InputError(f"{meta_path}: missing {', '.join(map(repr, missing))}")
    for key, (expected, ok) in _META_FIELDS.items():
        if key in meta and not ok(meta[key]):
            raise InputError(f"{meta_path}: {key}: expected {expected}, got {meta[key]!r}")
    return meta


def _check_size(path: str, meta_path: str, image: np.ndarray, meta: dict, verdict: str) -> None:
    """InputError naming both files when the JSON's resolution is not the EXR's size."""
    if "resolution" in meta and list(image.shape[1::-1]) != meta["resolution"]:
        raise InputError(
            f"{path} is {image.shape[1]}x{image.shape[0]} pixels but {os.path.basename(meta_path)} says"
            f" {meta['resolution'][0]}x{meta['resolution'][1]} (its resolution): {verdict}"
        )


def read_part(path: str) -> tuple[ReferencePart, dict]:
    """A part written by ``sss_lab reference`` and its description: the EXR's Combined pass,
    samples, seed (and what was rendered) from the JSON beside it."""
    meta_path = sidecar(path)
    if not os.path.isfile(meta_path):
        raise InputError(f"{path}: no {os.path.basename(meta_path)} beside it (samples and seed of the part)")
    meta = read_meta(meta_path, required=("samples", "seed"))
    image = exr.read_passes(path)["Combined"]
    _check_size(path, meta_path, image, meta, "they are not one part")
    return ReferencePart(image=image, samples=meta["samples"], seed=meta["seed"], source=path), meta


def read_parts(paths: Sequence[str]) -> tuple[list[ReferencePart], list[dict]]:
    """Read parts and check that they render the same thing (scene, frame, size, method)."""
    parts, metas = [], []
    for path in paths:
        part, meta = read_part(path)
        parts.append(part)
        metas.append(meta)
    keys = ("fingerprint", "frame", "resolution", "scene")
    for key in keys:
        values = {json.dumps(m.get(key)) for m in metas}
        if len(values) > 1:
            detail = ", ".join(f"{os.path.basename(p)}: {m.get(key)!r}" for p, m in zip(paths, metas, strict=True))
            raise InputError(f"the parts differ in {key} ({detail}); merge parts of one scene, frame and size only")
    unknown = [os.path.basename(p) for p, m in zip(paths, metas, strict=True) if not m.get("fingerprint")]
    if len(metas) > 1 and unknown:
        raise InputError(
            f"{', '.join(unknown)}: no scene fingerprint in the JSON beside it, so nothing says the parts render"
            " the same scene; render the parts with sss_lab reference (which records it)"
        )
    return parts, metas


def write_merged(path: str, merged: MergedReference, meta: dict | None = None, *, overwrite: bool = False) -> list[str]:
    """Write the merged reference (and its halves) as a multilayer EXR plus a JSON beside it;
    returns the paths written."""
    layers = {MERGED_LAYER: merged.image}
    if merged.halves is not None:
        layers.update(zip(HALF_LAYERS, merged.halves, strict=True))
    header = {"sss_lab_samples": merged.samples, "sss_lab_seeds": ",".join(map(str, merged.seeds))}
    json_path = sidecar(path)
    if not overwrite and os.path.exists(json_path):
        raise FileExistsError(f"{json_path} already exists; refusing to overwrite it (choose another output name)")
    exr.write_layers(path, layers, header, overwrite=overwrite)
    data = dict(meta or {})
    data.update(
        {
            "samples": merged.samples,
            "seeds": list(merged.seeds),
            "part_samples": list(merged.part_samples) if merged.part_samples else None,
            "half_samples": list(merged.half_samples) if merged.half_samples else None,
            "half_seeds": [list(s) for s in merged.half_seeds] if merged.half_seeds else None,
            "noise_floor_whole_image": noise_floor(merged),
        }
    )
    from ..base.files import write_text

    write_text(json_path, json.dumps(data, indent=2) + "\n")
    return [path, json_path]


def _header_record(path: str, meta_path: str, header: dict, meta: dict) -> tuple[int, tuple[int, ...] | None]:
    """(samples, seeds) that ``write_merged`` put in the EXR's header; InputError when the file
    has no such record (it was not written by ``merge-reference``: a passes file, typically) or
    the JSON beside it lacks the samples and seeds a merge writes."""
    missing = [k for k in ("samples", "seeds") if meta.get(k) is None] if os.path.isfile(meta_path) else []
    if "sss_lab_samples" not in header or missing:
        name = os.path.basename(meta_path)
        if "materials" in meta and "camera" in meta:
            why = f"{name} is the scene description of a passes file"
        elif missing:
            why = f"{name} has no {' or '.join(map(repr, missing))}"
        else:
            why = "its header has no sss_lab_samples"
        raise InputError(
            f"{path}: not a merged reference ({why}); expected a reference merged by sss_lab merge-reference"
            " from the parts of sss_lab reference"
        )
    samples = header["sss_lab_samples"]
    try:
        count = int(samples)
        text = str(header.get("sss_lab_seeds", "")).strip()
        seeds = tuple(int(v) for v in text.split(",")) if text else None
    except (TypeError, ValueError):
        raise InputError(
            f"{path}: its header's sss_lab_samples {samples!r} or sss_lab_seeds {header.get('sss_lab_seeds')!r}"
            " is not what sss_lab merge-reference writes; merge the parts again"
        ) from None
    if not 1 <= count <= len(seeds or (0,)) * CYCLES_MAX_SAMPLES:
        raise InputError(
            f"{path}: its header records {count} samples for {len(seeds or ())} seed(s); expected 1 to"
            f" {CYCLES_MAX_SAMPLES} per part (the most one Cycles render takes): merge the parts again"
        )
    return count, seeds


def _check_merged_meta(path: str, meta_path: str, meta: dict, recorded: tuple[int, tuple[int, ...] | None]) -> None:
    """InputError naming the JSON and the field when its samples and seeds disagree with what it
    records of the parts (each part's samples, the halves' samples and seeds, the part files) or
    with the EXR's own record, or claim more than the parts can hold."""
    samples, seeds = meta["samples"], meta["seeds"]
    if len(set(seeds)) != len(seeds) or not seeds:
        raise InputError(f"{meta_path}: seeds: expected distinct seeds, one per part, got {seeds!r}")
    # What the JSON records of the parts, each a sum the merged samples must equal.
    sums = []
    if meta.get("part_samples") is not None:
        if len(meta["part_samples"]) != len(seeds):
            raise InputError(
                f"{meta_path}: part_samples holds {len(meta['part_samples'])} counts for {len(seeds)} seeds"
                f" {seeds}; expected one per part"
            )
        sums.append(("part_samples " + " + ".join(map(str, meta["part_samples"])), sum(meta["part_samples"])))
    if meta.get("half_samples") is not None:
        sums.append(("half_samples " + " + ".join(map(str, meta["half_samples"])), sum(meta["half_samples"])))
    for what, total in sums:
        if samples != total:
            raise InputError(
                f"{meta_path}: samples {samples} disagrees with its {what} = {total}; the JSON was edited or is"
                " another reference's: merge the parts again"
            )
    if samples != recorded[0]:
        raise InputError(
            f"{meta_path}: samples {samples} disagrees with {os.path.basename(path)}'s own record of"
            f" {recorded[0]} samples; the JSON was edited or is another reference's: merge the parts again"
        )
    if samples < len(seeds) or samples > len(seeds) * CYCLES_MAX_SAMPLES:
        raise InputError(
            f"{meta_path}: samples {samples} for {len(seeds)} part(s): expected 1 to {CYCLES_MAX_SAMPLES} per part"
            " (the most one Cycles render takes); merge the parts again"
        )
    if recorded[1] is not None and sorted(seeds) != sorted(recorded[1]):
        raise InputError(
            f"{meta_path}: seeds {seeds} disagree with {os.path.basename(path)}'s own record of seeds"
            f" {list(recorded[1])}; merge the parts again"
        )
    if meta.get("half_seeds") is not None:
        both = [s for half in meta["half_seeds"] for s in half]
        if sorted(both) != sorted(seeds):
            raise InputError(
                f"{meta_path}: half_seeds {meta['half_seeds']} are not the seeds {seeds} split in two; merge the"
                " parts again"
            )
    if isinstance(meta.get("parts"), list) and len(meta["parts"]) != len(seeds):
        raise InputError(
            f"{meta_path}: parts names {len(meta['parts'])} file(s) for {len(seeds)} seeds {seeds}; merge the"
            " parts again"
        )


def read_merged(path: str) -> MergedReference:
    """A merged reference written by ``write_merged`` (the halves, samples and seeds included).

    Refused (InputError naming the file and what is wrong) when it is not one (a passes file, an
    EXR without ``write_merged``'s record of its samples), when the JSON beside it is damaged or
    disagrees with the EXR (its size, samples, seeds) or with itself (samples against the parts'
    and the halves' samples): a reference of the wrong weight would make every figure wrong."""
    contents = exr.read_layers(path)
    if MERGED_LAYER not in contents.layers:
        raise InputError(f"{path}: no layer {MERGED_LAYER!r}; expected a reference merged by sss_lab merge-reference")
    meta_path = sidecar(path)
    meta = read_meta(meta_path) if os.path.isfile(meta_path) else {}
    recorded = _header_record(path, meta_path, contents.header, meta)
    if meta:
        _check_merged_meta(path, meta_path, meta, recorded)
    _check_size(
        path, meta_path, contents.layers[MERGED_LAYER], meta, "the JSON is not this reference's; merge the parts again"
    )
    halves = None
    if all(name in contents.layers for name in HALF_LAYERS):
        first, second = (contents.layers[name] for name in HALF_LAYERS)
        halves = (first, second)
    half_samples = tuple(meta["half_samples"]) if halves is not None and meta.get("half_samples") else None
    if halves is not None and half_samples is None:
        raise InputError(f"{path}: the halves' sample counts are missing ({meta_path}); merge the parts again")
    samples = int(meta.get("samples") or recorded[0])
    seeds = tuple(meta.get("seeds") or recorded[1] or ())
    half_seeds = None
    if meta.get("half_seeds"):
        seeds_a, seeds_b = (tuple(int(v) for v in s) for s in meta["half_seeds"])
        half_seeds = (seeds_a, seeds_b)
    part_samples = tuple(meta["part_samples"]) if meta.get("part_samples") else None
    return MergedReference(
        image=contents.layers[MERGED_LAYER],
        samples=samples,
        seeds=seeds,
        halves=halves if half_samples else None,
        half_samples=half_samples,
        half_seeds=half_seeds,
        part_samples=part_samples,
    )
