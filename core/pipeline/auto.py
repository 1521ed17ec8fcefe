"""Model only what the scene requires: choose a technique per material from cheap features.

``choose`` looks at each subsurface material on a set of passes and measures, without running
any technique, how much the two things SSS adds to a plain diffuse render matter there:

- **diffusion** D: how much the material's visible diffuse light changes when it is spread over
  its footprint. Everything is measured on the 2 x 2 block means wholly inside the material (the
  blocks of the error measure ``compare`` uses, docs/references.md §8; a quarter of the pixels;
  larger blocks on a window wider than ``GRID`` blocks, each read at 2 x 2 of its pixels, so that
  the cost stays bounded at any resolution).
  The irradiance (Diffuse Direct + Indirect) is averaged, per channel, over a box of half-width
  2.5 d (the mean distance light travels under the Burley profile, docs/references.md §1; in
  whole blocks) at the material's median depth, inside the material only; D is the RMS of
  albedo x (averaged - original) relative to the mean of Combined (plus the light from behind).
  A footprint of 2.5 d under half a block (one pixel), or a flatly lit material, gives D = 0.
- **light from behind** B: the light the combined technique's transmission would add
  (``core/techniques/combined/technique.py``: back irradiance x per-channel Burley transmittance through the baked
  thickness), measured the same way. Needs the thickness map and its bake distance; without them
  B is 0 and said so.
- **energy** G, when the material carries a fit (``core/study/fit.py``): the light its fitted gain
  adds or removes. A technique fitted for the material corrects it; the others (and no SSS) keep
  it as error.

- **wide diffusion** W = D x min(1, widest footprint d in pixels / ``WIDE_PX``): the part of the
  diffusion spread over many pixels, where the separable filter's few taps and Burley's spiral
  differ most (on the fidelity suite neither is consistently better up to footprints of about
  13 px; at 84 px Burley's error is 18 % lower).

- **energy** V: how much the scattering techniques' default energy (``core/optics/energy.py``, "object":
  the light Cycles' random walk returns against Lambert as a function of the view angle, times a
  finite object's light through the baked thickness) changes the material's visible light,
  measured the same way (the view cosine from the Normal and Position passes; 0 without them, or
  for a method without tables). It does not depend on the footprint: a material far smaller than
  a pixel still gains from it.

A model (``Model``) predicts each technique's error from those numbers, error^2 = alpha D^2 +
beta B^2 + gamma + delta W^2 + epsilon V^2 (+ G^2 for a technique without a fit), with non-negative
coefficients learnt per technique by least squares on measured errors (``train``;
``benchmarks/auto.py`` learns them on the fidelity suite and validates the choice
leave-one-scene-out; the shipped coefficients are in ``auto_model.json`` beside this module, with
the command that made them). ``choose`` then takes, per material, the cheapest candidate (no SSS
included) whose predicted error is within ``max_error`` (relative) of the best predicted error;
candidates whose estimated costs are within ``COST_TOLERANCE`` of the cheapest count as equally
cheap, and the lower error decides among them. The cost of a technique is its work estimate,
pixels x (samples per pixel of its kernel, from its spec's ``footprint``, + one per light for a
technique whose spec says it adds light), times the technique's measured seconds per unit of work
(learnt with the coefficients: one sample of the separable filter and one of Burley's spiral do
not cost the same).

**Rungs** (``choose(rungs=True)``; by default the candidates are the techniques at their default
quality, which lose less against the best: ``DEFAULT_MAX_ERROR``). Each rung of a
technique's quality ladder (its spec's ``qualities``, the runs ``compare`` sweeps: Burley at 8 to 64
samples, SSSS at 11 to 25 taps, the combined technique with SSSS at 11 taps or Burley at 16) and
each diffusion's rungs with its energy stage off (``ENERGY_OFF``, Lambert's energy) is a candidate
of its own, named ``technique option=value ...`` (``variants``), with its own coefficients learnt
from its own measured errors and its own measured seconds per unit of work (a rung's time is not
its samples' share of the default's: each run has a fixed part). The energy stage off is what the
feature V decides: its coefficient epsilon is learnt like the others. Between the rungs of one
technique the cheapest within the margin stands for it (their costs rank reliably: the same
kernels, fewer samples or a stage less); ``COST_TOLERANCE`` applies between techniques. A model
without coefficients for a rung (one learnt before the rungs) leaves that rung out, and says so;
a stored model naming a rung no ladder has is an error. A technique fitted for the material
(``core/study/fit.py``) keeps its energy stage: the fit ran with it, and its gain holds that energy.

**With a fit** (``calibrate``, ``core/study/fit.py``) the error is measured, not predicted: the fit
scores each technique it fitted against a Cycles render of the same view on held-out blocks of
the material (its provenance, ``info["heldout_after"]``). When a material carries such a
measurement for two or more techniques, made on renders of the same sample count, ``choose``
takes the cheapest of the measured techniques whose measured error is within ``max_error`` of
the lowest measured one and whose predicted error is within ``max_error`` of that technique's
predicted error; the techniques the fit did not measure are not candidates then (a prediction and
a measurement are not on the same footing). The measurement holds the fit render's Monte Carlo
noise, which adds alike to every technique's error and so brings the measured errors closer
together than the techniques are (hence the prediction's check as well), and covers the blocks wholly inside the
material (``core.study.fit.BOX`` pixels across), not the pixels at its silhouette. The fit measures each
technique at its default quality; a rung of a measured technique is judged by that measurement
times its predicted error over the default's.

``apply_auto`` carries the choice out: each material gets its chosen technique's result at its chosen rung
(``core.pipeline.apply.apply``), composited into ``SSSLab.auto.Image`` / ``SSSLab.auto.SSS``.

The features are NumPy, the reference. On the compiled backend (``core.compute.backend``) the loops that
read the passes (the material's window and pixels, the block means, the diffusion's box means)
are kernels (``core/pipeline/_kernels.py``) with the same operations in the same order, equal to the bit; in
check mode each is compared with its NumPy code with a bound of 0.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..base import arrays
from ..base.errors import InputError
from ..base.jsonfile import read_json
from ..compute import backend
from ..optics.energy import SLAB_ABOVE, entry_gain, slab_factors, unseen_light
from ..optics.medium import medium_of
from ..scene.exr import Passes
from ..scene.inputs import read_scene
from ..scene.scene import MaterialSSS, SceneDescription
from ..techniques.combined.technique import transmission, view_cosine
from ..techniques.registry import TECHNIQUES, get_spec
from . import apply as core_apply
from .fit_params import INFO, OFF, fitted
from .mapping import burley_d, mean_free_path, technique_params
from .plan import EXACT_FLOAT32, Plan, fractional_indices, index_map, index_warning, plan, required_passes


def _kernels():
    """This package's compiled kernels (``_kernels.py``), loaded on first use."""
    return backend.kernels(__package__)


#: The name ``apply --methods auto`` and the output layers (``SSSLab.auto.*``) use.
AUTO = "auto"
#: The candidate that leaves a material as it is (no SSS).
NONE = "none"
#: Default ``max_error``: a technique may be predicted (or measured) up to 3 % worse than the best
#: and still be chosen when it is cheaper. Leave-one-scene-out on the 17 scenes of the fidelity suite
#: (``benchmarks/auto.py``, README *Auto*), choosing among the techniques' default qualities (the
#: default, ``rungs=False``): mean regret against the truly best technique without / with a fit
#: +2.8 / +0.9 % at 0.03 (+3.2 / +0.9 % and +3.4 / +1.6 % in two later runs: the timings decide
#: between SSSS and Burley where their costs are within ``COST_TOLERANCE``), +3.2 / +1.4 % at 0.05,
#: +3.3 / +3.1 % at 0.10; the time saved against always running the combined technique 27 / 20 %,
#: 25 / 19 %, 28 / 27 %. With the rungs the regret was +5.3 / +2.8 % at 0.03 and +6.3 / +7.5 % at
#: 0.10 (the model does not see what 8 of Burley's samples lose at a small footprint: +18 % on the
#: front-lit skin sphere).
DEFAULT_MAX_ERROR = 0.03
#: Mean distance light travels under the Burley profile of d: 2.5 d (the first moment of
#: R(r) 2 pi r = (e^{-r/d} + e^{-r/(3d)}) / (4 d), docs/references.md §1).
MEAN_DISTANCE = 2.5
#: Widest box (pixels, half-width) the diffusion feature averages over; wider footprints change
#: little more and would cost more than the feature is worth.
MAX_BOX = 64
#: Footprint (the widest channel's d, pixels) from which the diffusion counts wholly as wide (W = D):
#: the width from which Burley's default also cleans its scattered light (``core/techniques/burley/technique.py``).
WIDE_PX = 32.0
#: Blocks of the error measure (as ``compare`` and the fidelity suite: 2 x 2).
BOX = 2
#: Most blocks across a material's window the features are measured on (larger blocks beyond), at
#: every resolution, the fidelity suite's 128 px frames included, where the model's coefficients
#: are learnt: a material seen at a higher resolution is measured on no finer a grid than the one
#: its error model knows, and the features' cost stays that of the suite's size. 32: the features
#: are statistics over the material, and most of their cost is per block (table reads, the light
#: from behind); leave-one-scene-out with the fit (``benchmarks/auto.py --fit``), 64 -> 32 gave
#: +6.0 -> +6.4 % mean regret (the runs' spread is about a point) and the choice 3.9 -> 2.9 ms a
#: scene at 512 px (README).
GRID = 32
#: Estimated costs within this share of the cheapest count as equal, and the lower error decides
#: between them: the measured seconds the costs come from vary by about this much from run to run
#: on a loaded machine (SSSS and Burley cost the same to within 3 % over the fidelity suite, and
#: three runs of ``benchmarks/auto.py`` on one commit ranked them differently, which changed
#: auto's mean regret by 3 points).
COST_TOLERANCE = 0.10
MODEL_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "auto_model.json")


@dataclass
class Features:
    """What ``choose`` measures on one material (see the module docstring)."""

    name: str
    index: int
    pixels: int = 0
    #: The profile's d per channel (R, G, B) in pixels at the material's median depth.
    footprint_px: tuple[float, float, float] = (0.0, 0.0, 0.0)
    diffusion: float = 0.0
    wide: float = 0.0
    view: float = 0.0
    back: float = 0.0
    #: Light from behind over the visible diffuse light, summed over the material (a share).
    back_share: float = 0.0
    #: Median slab thickness read from the baked map over the mean d (None without a map).
    thickness_over_d: float | None = None
    energy: float = 0.0
    #: Techniques the material carries a fit for.
    fitted: tuple[str, ...] = ()
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


#: The energy stage's setting a candidate runs without it (``core/optics/energy.py``: Lambert's energy,
#: the passes' light spread as it is): the stage costs a fixed share of each diffusion's time.
ENERGY_OFF = {"energy": "lambert"}


@functools.cache
def _variants(technique: str) -> tuple[tuple[str, tuple], ...]:
    spec = get_spec(technique)
    out = []
    for k, rung in enumerate(spec.qualities):
        base = {} if k == spec.default_quality else dict(rung)
        runs = [base, {**base, **ENERGY_OFF}] if "energy" in spec.keywords else [base]
        out += [(candidate_name(spec.name, o), tuple(o.items())) for o in runs]
    return tuple(out)


def candidate_name(technique: str, options) -> str:
    """``burley n_samples=16 energy=lambert``: the technique's name and the options it runs with
    (none: its default quality)."""
    return technique + "".join(f" {k}={v}" for k, v in dict(options).items())


def variants(technique: str) -> dict[str, dict]:
    """{candidate name: options} of ``technique``: each rung of its quality ladder (its spec's
    ``qualities``, the runs ``compare`` sweeps; the default rung is the technique's name alone),
    and for a technique with an energy stage each rung with the stage off (``ENERGY_OFF``)."""
    return {name: dict(options) for name, options in _variants(get_spec(technique).name)}


def technique_of(candidate: str) -> str:
    """The technique a candidate name runs (``burley n_samples=16``: burley)."""
    return candidate.split(" ", 1)[0]


def options_of(candidate: str) -> dict:
    """The options a candidate runs its technique with; InputError naming it when its technique is
    not registered or it is no rung of the technique's quality ladder (nor one without the energy
    stage)."""
    technique = technique_of(candidate)
    if technique not in TECHNIQUES:
        raise InputError(
            f"candidate {candidate!r}: no technique {technique!r}; expected one of: {', '.join(TECHNIQUES)}"
        )
    known = variants(technique)
    if candidate not in known:
        raise InputError(
            f"candidate {candidate!r}: not a rung of {technique}'s quality ladder; expected one of: {', '.join(known)}"
        )
    return known[candidate]


@dataclass(frozen=True)
class Model:
    """Per candidate (``NONE``, a technique at its default quality, or one of its rungs: ``variants``):
    (alpha, beta, gamma[, delta[, epsilon]]) of error^2 = alpha D^2 + beta B^2 + gamma + delta W^2 +
    epsilon V^2 (delta and epsilon 0 when not given)."""

    coefficients: dict
    #: What it was learnt on (scene names) and by which command.
    trained_on: tuple[str, ...] = ()
    command: str = ""
    #: Measured seconds per unit of work (pixels x samples) per candidate: the techniques' kernels
    #: differ in what one sample costs, and a rung's time is not its samples' share of its default's
    #: (each has a fixed part: the energy stage, the compositing), so each rung has its own rate.
    seconds_per_work: dict = field(default_factory=dict)

    def seconds(self, candidate: str, work: float) -> float:
        """Estimated seconds of ``candidate`` for ``work``; a rung without a measurement counts at its
        technique's rate, a technique without one at the median rate of the others (at 1 when none
        is measured)."""
        if candidate == NONE:
            return 0.0
        rate = self.seconds_per_work.get(candidate, self.seconds_per_work.get(technique_of(candidate)))
        if rate is None:
            known = sorted(self.seconds_per_work.values())
            rate = known[len(known) // 2] if known else 1.0
        return rate * work

    def predict(self, candidate: str, f: Features) -> float:
        alpha, beta, gamma, *rest = self.coefficients[candidate]
        e2 = alpha * f.diffusion**2 + beta * f.back**2 + gamma
        e2 += sum(c * v**2 for c, v in zip(rest, (f.wide, f.view), strict=False))
        if candidate == NONE or technique_of(candidate) not in f.fitted:
            e2 += f.energy**2
        return math.sqrt(max(e2, 0.0))

    def to_dict(self) -> dict:
        return {
            "coefficients": {k: list(v) for k, v in self.coefficients.items()},
            "trained_on": list(self.trained_on),
            "command": self.command,
            "seconds_per_work": dict(self.seconds_per_work),
            "definition": "relative error^2 = alpha D^2 + beta B^2 + gamma + delta W^2 + epsilon V^2 per candidate"
            " (a technique at its default quality, or 'technique option=value ...': a rung of its quality ladder,"
            " or without its energy stage); seconds = rate x pixels x samples (core/pipeline/auto.py)",
        }

    @classmethod
    def from_dict(cls, data: dict, where: str = "model") -> Model:
        try:
            coefficients = {str(k): tuple(float(x) for x in v) for k, v in dict(data["coefficients"]).items()}
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{where}: expected {{'coefficients': {{candidate: [alpha, beta, gamma]}}}}") from None
        for k, v in coefficients.items():
            if len(v) not in (3, 4, 5) or not all(math.isfinite(x) and x >= 0 for x in v):
                raise InputError(f"{where}: coefficients of {k!r} must be three to five finite numbers >= 0, got {v}")
        if NONE not in coefficients:
            raise InputError(f"{where}: no coefficients for {NONE!r} (no SSS), which every choice compares against")
        try:
            rates = {str(k): float(v) for k, v in dict(data.get("seconds_per_work", {})).items()}
        except (TypeError, ValueError):
            raise InputError(f"{where}: seconds_per_work: expected {{technique: seconds per unit of work}}") from None
        if not all(math.isfinite(v) and v > 0 for v in rates.values()):
            raise InputError(f"{where}: seconds_per_work: expected positive numbers, got {rates}")
        for k in [*coefficients, *rates]:
            if k != NONE:
                try:
                    options_of(k)
                except InputError as exc:
                    raise InputError(f"{where}: {exc}") from None
        return cls(coefficients, tuple(data.get("trained_on", ())), str(data.get("command", "")), rates)


def load_model(path: str = MODEL_PATH) -> Model:
    """The model stored at ``path`` (default: the one shipped beside this module)."""
    try:
        data = read_json(path, "an auto model")
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read the auto model ({exc})") from None
    return Model.from_dict(data, path)


# --- features ---------------------------------------------------------------------------------


def _box_sum(a: np.ndarray, h: int) -> np.ndarray:
    """Sum of ``a`` (H, W) over the (2h+1)^2 box around each pixel (clipped at the borders)."""
    H, W = a.shape
    s = np.zeros((H + 1, W + 1), np.float64)
    s[1:, 1:] = np.cumsum(np.cumsum(a, axis=0), axis=1)
    y0 = np.clip(np.arange(H) - h, 0, H)
    y1 = np.clip(np.arange(H) + h + 1, 0, H)
    x0 = np.clip(np.arange(W) - h, 0, W)
    x1 = np.clip(np.arange(W) + h + 1, 0, W)
    return s[y1][:, x1] - s[y0][:, x1] - s[y1][:, x0] + s[y0][:, x0]


def _blurred(e: np.ndarray, mask: np.ndarray, h: int) -> np.ndarray:
    """Mean of ``e`` (H, W) over the box of half-width ``h`` around each pixel, inside ``mask`` only."""
    m = mask.astype(np.float64)
    num = _box_sum(np.where(mask, e, 0.0), h)
    den = _box_sum(m, h)
    return np.where(den > 0, num / np.maximum(den, 1e-300), e)


def _blurred_change(e: np.ndarray, mask: np.ndarray, h: int) -> np.ndarray:
    """``_blurred(e, mask, h) - e`` as float32 (``e`` (H, W) float32): a kernel on the compiled
    backend (``core.pipeline._kernels.blurred_change``)."""

    def reference():
        return (_blurred(e, mask, h) - e).astype(np.float32)

    def kernel():
        out = np.empty(e.shape, np.float32)
        backend.run_serial(_kernels().blurred_change, e, mask, h, out)
        return out

    return _kernel_or_reference("auto box means", reference, kernel, e.dtype == np.float32)


def _kernel_or_reference(name: str, reference, kernel, fits: bool = True):
    """``kernel()`` on the compiled backend where its inputs ``fits`` it (else and on NumPy
    ``reference()``); in check mode compared with ``reference()``, equal to the bit."""
    mode = backend.active()
    if mode == "numpy" or not fits:
        return reference()
    result = kernel()
    if mode == "check":
        _same_bits(name, reference(), result)
    return result


def _same_bits(name: str, expected, result) -> None:
    """``core.pipeline.apply.bits_equal`` over arrays, and tuples of them, slices or None."""
    if isinstance(expected, tuple) and isinstance(result, tuple) and len(expected) == len(result):
        for a, b in zip(expected, result, strict=True):
            _same_bits(name, a, b)
    elif isinstance(expected, np.ndarray) and isinstance(result, np.ndarray):
        core_apply.bits_equal(name, expected, result)
    elif isinstance(expected, np.ndarray) or isinstance(result, np.ndarray) or expected != result:
        raise backend.BackendMismatch(f"{name}: the compiled result differs from the NumPy code's")


class _Shared:
    """What ``features`` reads, found once per call of ``choose``: the Material Index map and the
    passes (read-only views; each material's features clean only its own window of them)."""

    def __init__(self, passes: Passes, scene: SceneDescription):
        self.raw_index = passes["Material Index"]
        self._passes = passes
        self.combined = passes["Combined"][..., :3]
        self.albedo = passes["Diffuse Color"][..., :3]
        have = "Diffuse Direct" in passes and "Diffuse Indirect" in passes
        self.direct = passes["Diffuse Direct"] if have else None
        self.indirect = passes["Diffuse Indirect"] if have else None
        self.depth = passes.get("Depth")
        have_np = "Normal" in passes and "Position" in passes
        self.normal_position = (passes["Normal"], passes["Position"]) if have_np else None
        aov = scene.thickness_aov
        self.thickness = None
        self.missing_back = [p for p in ("Normal", "Position", aov) if p not in passes]
        if not self.missing_back:
            t = passes[aov]
            self.thickness = t if t.ndim == 2 else t[..., 0]
            self.normal = passes["Normal"]
            self.position = passes["Position"]

    @functools.cached_property
    def index(self) -> np.ndarray:
        """The Material Index map (``core.pipeline.plan.index_map``), made at its first use: the compiled
        backend's window (``_window``) reads the pass without it."""
        return index_map(self._passes)


def _block_means(a: np.ndarray, size: int) -> np.ndarray:
    """The means of ``a`` ((H, W) or (H, W, C), cropped to a multiple of ``size``) over
    ``BOX`` x ``BOX`` pixels of each ``size`` x ``size`` block, one at the centre of each of its
    ``BOX`` x ``BOX`` equal parts (``_sample_offsets``), float32, NaN and +-Inf read as 0 (as
    ``core.pipeline.apply.clean`` reads them).

    With blocks of ``BOX`` (a window of at most ``BOX`` x ``GRID`` pixels) these are the blocks of the error measure
    (``core.study.metrics.box_downsample``), every pixel read. Larger blocks (a window wider than
    ``GRID`` blocks) are represented by those ``BOX`` x ``BOX`` pixels: the features are
    statistics over at most ``GRID`` x ``GRID`` blocks, their inputs hold the same noise per value
    as the blocks the model was learnt on, and the cost no longer grows with the resolution
    (reading every pixel of a 512 px window was most of ``choose``'s time, which ``auto`` spends
    before any technique runs). Summed in float64 from strided views, each column of the sample
    first, then across: the additions of the whole-block mean for blocks of ``BOX``."""
    assert size % BOX == 0, f"blocks of {size}: expected a multiple of {BOX}"

    def kernel():
        view = a if a.ndim == 3 else a[..., None]
        out = np.empty((a.shape[0] // size, a.shape[1] // size, view.shape[2]), np.float32)
        backend.run_serial(_kernels().block_means, view, size, size // BOX, float(BOX * BOX), out)
        return out if a.ndim == 3 else out[..., 0]

    return _kernel_or_reference("auto block means", lambda: _block_means_numpy(a, size), kernel, a.dtype == np.float32)


def _block_means_numpy(a: np.ndarray, size: int) -> np.ndarray:
    """``_block_means`` in NumPy, the reference."""
    h, w = a.shape[0] // size * size, a.shape[1] // size * size
    for clean in (False, True):
        total = np.zeros((h // size, w // size) + a.shape[2:], np.float64)
        for dx in _sample_offsets(size):
            column = np.zeros_like(total)
            for dy in _sample_offsets(size):
                v = a[dy:h:size, dx:w:size].astype(np.float32, copy=False)
                column += np.where(np.isfinite(v), v, 0.0) if clean else v
            total += column
        # float32 values summed in float64 cannot overflow: a sum that is not finite read a NaN or
        # an infinity (checked on the sums, a small array: the strided samples are slow to scan).
        if clean or np.isfinite(total).all():
            break
    return (total / (BOX * BOX)).astype(np.float32)


def _sample_offsets(size: int) -> range:
    """The rows (and columns) of a ``size`` x ``size`` block that ``_block_means`` reads: the
    centres of its ``BOX`` x ``BOX`` equal parts (every row for blocks of ``BOX``)."""
    part = size // BOX
    return range(part // 2, size, part)


def _block_inside(mask: np.ndarray, size: int) -> np.ndarray:
    """The blocks (as ``_block_means``) whose sampled pixels are all inside ``mask``."""
    h, w = mask.shape[0] // size * size, mask.shape[1] // size * size
    inside = np.ones((h // size, w // size), bool)
    for dy in _sample_offsets(size):
        for dx in _sample_offsets(size):
            inside &= mask[dy:h:size, dx:w:size]
    return inside


def _crop(mask: np.ndarray) -> tuple[slice, slice]:
    """The bounding box of ``mask``, its start on even rows and columns (so that the 2 x 2 blocks
    inside it are the blocks of the whole image, as the error measure takes them)."""
    box = arrays.bounding_box(mask)
    assert box is not None, "a window of no pixel"
    rows, cols = box
    return slice(rows.start // BOX * BOX, rows.stop), slice(cols.start // BOX * BOX, cols.stop)


def _window(sh: _Shared, index: int) -> tuple[tuple[slice, slice], np.ndarray] | None:
    """The material's window (``_crop`` of its pixels) and its pixels there whose Combined is
    finite, or None when it has no pixel: on the compiled backend read from the Material Index
    pass by two kernels (``core.pipeline._kernels.index_box``, ``index_window``) instead of the whole
    frame's int64 map, its comparison and the window's finiteness."""

    def reference():
        on = sh.index == index
        if not on.any():
            return None
        win = _crop(on)
        seen = sh.combined[win]
        return win, (on[win] if arrays.all_finite(seen) else on[win] & core_apply.finite(seen))

    def kernel():
        box = np.zeros(4, np.int64)
        backend.run_serial(_kernels().index_box, sh.raw_index, index, box)
        if box[1] == 0:
            return None
        win = slice(int(box[0]) // BOX * BOX, int(box[1])), slice(int(box[2]) // BOX * BOX, int(box[3]))
        mask = np.empty((win[0].stop - win[0].start, win[1].stop - win[1].start), bool)
        backend.run_serial(
            _kernels().index_window,
            sh.raw_index,
            index,
            sh.combined,
            win[0].start,
            win[1].start,
            mask,
        )
        return win, mask

    # A float32 holds every index below 2^24 exactly (as ``core.pipeline.plan`` compares them).
    fits = sh.raw_index.dtype == np.float32 and sh.raw_index.ndim == 2 and 0 <= index < EXACT_FLOAT32
    fits = fits and sh.combined.ndim == 3 and sh.combined.shape[2] >= 3
    return _kernel_or_reference("auto window", reference, kernel, fits and sh.combined.dtype == np.float32)


def _rms(term: np.ndarray, keep: np.ndarray, base: np.ndarray) -> float:
    """RMS of ``term`` over ``keep`` relative to the mean of ``base`` there."""
    mean = float(np.mean(base[keep]))
    if mean <= 0:
        return 0.0
    return float(np.sqrt(np.mean(np.square(term[keep], dtype=np.float64)))) / mean


def _energy_change(material, scene, sh, at, keep, albedo, e, visible, base) -> float:
    """V: the RMS change the scattering techniques' default energy (``core.optics.energy.apply_energy``,
    "object") makes to the material's visible light, relative to the mean of ``base``: the entry's
    view dependence (each channel's total kept) times the finite object's light, computed as that
    function does on the blocks (the view cosine from the Normal and Position passes; the unseen
    side's light by the energy stage's own ``unseen_light``, a kernel on the compiled backend)."""
    mean = float(np.mean(base[keep]))
    if mean <= 0:
        return 0.0
    normal, position = (at(a) for a in sh.normal_position)
    a = np.clip(albedo[keep], 0.0, 1.0).astype(np.float32)
    lit = visible[keep].astype(np.float32)
    gain = entry_gain(material.method, a, view_cosine(normal, position, scene.camera)[keep])
    before = lit.astype(np.float64).sum(axis=0)
    after = (lit * gain).astype(np.float64).sum(axis=0)
    gain = gain * np.where(after > 0, before / np.where(after > 0, after, 1.0), 1.0).astype(np.float32)[None, :]
    out = lit
    distance = material.thickness_distance
    if sh.thickness is not None and distance and material.method in SLAB_ABOVE:
        tau = np.clip(at(sh.thickness)[keep].astype(np.float64), 0.0, 1.0)
        if scene.thickness_convention == "thickness":
            tau = 1.0 - tau
        x = distance * np.sqrt(1.0 - tau)
        ell = np.maximum(np.asarray(mean_free_path(material), np.float64), 1e-30)
        f_above, f_below = slab_factors(material.method, a, x[:, None] / ell[None, :])
        unseen = unseen_light(
            keep,
            diffuse=e,
            albedo=albedo,
            pre_post=False,
            normal=normal,
            position=position,
            lights=scene.lights,
            lamps=True,
        )
        if unseen is not None:
            out = lit * f_above + a * f_below * unseen.astype(np.float32)[None, :]
    change = (out * gain).astype(np.float64) - lit
    return float(np.sqrt(np.mean(np.square(change)))) / mean


@backend.one_thread()  # its kernels read at most GRID x GRID blocks: a second thread only waits
def features(passes: Passes, scene: SceneDescription, material: MaterialSSS, *, _shared=None) -> Features:
    """The features of ``material`` on ``passes`` (module docstring); pure NumPy, no technique run.

    Measured on the 2 x 2 block means of the material's bounding box (the blocks the error measure
    uses, blocks wholly inside the material; larger blocks when the window is wider than ``GRID``
    blocks, each read at 2 x 2 of its pixels: ``_block_means``), which costs a quarter of the
    pixels or less; a material too small for one whole block is measured on its pixels. The
    material's pixel count (its work estimate) and the finiteness of Combined are taken on every
    pixel of its window; its median depth on one pixel in k x k for blocks of 2 k."""
    start = time.perf_counter()
    sh = _shared or _Shared(passes, scene)
    f = Features(name=material.name or str(material.index), index=material.index)
    # Fits that hold values (not a technique switched off by calibrate, which holds none).
    f.fitted = tuple(t for t in material.fit if fitted(material.fit, t) and not fitted(material.fit, t).get(OFF))
    found = _window(sh, material.index)
    if found is not None:
        win, mask = found
        f.pixels = int(mask.sum())
    if not f.pixels:
        f.notes.append("no pixel on screen")
        return f
    keep, step = mask, 1
    # Blocks of 2 x 2 pixels, larger on a large window so that a material is measured on at most
    # about GRID x GRID blocks: the features are statistics, and their cost stays bounded at any
    # resolution (at 128 px, the fidelity suite's size, a window of up to 64 px is measured on the
    # blocks of the error measure, a wider one on 4 x 4 blocks).
    size = BOX * max(1, math.ceil(max(mask.shape) / (BOX * GRID)))
    if min(mask.shape) >= size:
        blocks = _block_inside(mask, size)
        if blocks.any():
            keep, step = blocks, size

    read: dict[int, np.ndarray] = {}

    def at(a):
        """``a`` on the window, NaN/Inf as 0, as block means when measured on blocks (each pass
        read once: the light from behind and the energy read the Normal, Position and thickness
        passes both; a copy each time, since the callers are free to change what they get)."""
        if id(a) not in read:
            read[id(a)] = core_apply.clean(a[win]) if step == 1 else _block_means(a[win], step)
        return read[id(a)].copy()

    combined = at(sh.combined)
    albedo = at(sh.albedo)
    e = None if sh.direct is None else at(sh.direct) + at(sh.indirect)
    d = np.asarray(burley_d(material), np.float64)
    scales = [float(v) for v in (fitted(material.fit, t).get("d_scale") for t in f.fitted) if v]
    if scales:
        d = d * float(np.median(scales))
    if e is None:
        f.notes.append("no Diffuse Direct/Indirect passes: diffusion not measured")
    z = None
    if sh.depth is not None:
        k = max(1, step // BOX)  # on larger blocks, a pixel in k x k: the median of a sample
        zs = sh.depth[win][::k, ::k][mask[::k, ::k]]
        zs = zs[np.isfinite(zs) & (zs > 0) & (zs < arrays.BACKGROUND_DEPTH)]
        z = float(np.median(zs)) if zs.size else None
    if z is not None:
        ppu = float(scene.camera.pixels_per_unit(np.array([z], np.float32))[0])
        r, g, b = (float(v) * ppu for v in d)
        f.footprint_px = (r, g, b)
    visible = albedo * e if e is not None else combined
    # Light from behind, as the combined technique's transmission would add it.
    light = None
    tr_fit = next((fitted(material.fit, t) for t in f.fitted if "transmission_d_su" in fitted(material.fit, t)), {})
    distance = material.thickness_distance
    if sh.missing_back:
        f.notes.append(f"no {', '.join(sh.missing_back)} pass: light from behind not measured")
    elif not distance:
        f.notes.append("the thickness map has no bake distance: light from behind not measured")
    else:
        t_map = at(sh.thickness)
        light = transmission(
            normal=at(sh.normal),
            position=at(sh.position),
            thickness=t_map,
            mask=keep,
            lights=scene.lights,
            d_su=tuple(tr_fit.get("transmission_d_su", tuple(mean_free_path(material)))),
            thickness_distance_su=distance,
            transmission_scale=tr_fit.get("transmission_scale", 1.0),
            thickness_convention=scene.thickness_convention,
            medium=medium_of(material),
            albedo=albedo,
            camera=scene.camera,
        )
        t_lin = t_map if scene.thickness_convention == "translucency" else 1.0 - t_map
        x = distance * np.sqrt(1.0 - np.clip(t_lin[keep], 0.0, 1.0))
        if float(d.mean()) > 0:
            f.thickness_over_d = float(np.median(x)) / float(d.mean())
    # The error measure divides by the reference's mean, which holds the light from behind too.
    base = combined if light is None else combined + light
    if e is not None and z is not None:
        change = np.zeros(e.shape, np.float32)
        for c in range(3):
            half = min(int(round(MEAN_DISTANCE * f.footprint_px[c] / step)), MAX_BOX)
            if half < 1:
                continue  # the light stays within its block
            change[..., c] = _blurred_change(e[..., c], keep, half)
        f.diffusion = _rms(albedo * change, keep, base)
        f.wide = f.diffusion * min(1.0, max(f.footprint_px) / WIDE_PX)
    if sh.normal_position is None:
        f.notes.append("no Normal/Position pass: the techniques' energy not measured")
    elif e is not None:
        f.view = _energy_change(material, scene, sh, at, keep, albedo, e, visible, base)
    if light is not None:
        f.back = _rms(light, keep, base)
        total = float(np.sum(visible[keep]))
        f.back_share = float(np.sum(light[keep])) / total if total > 0 else 0.0
    fitted_gains = [fitted(material.fit, t).get("gain") for t in f.fitted]
    gains = [np.asarray(g, np.float32) for g in fitted_gains if g is not None]
    if gains and e is not None:
        g = np.median(np.stack(gains), axis=0)
        f.energy = _rms(visible * (g - 1.0), keep, base)
    f.seconds = time.perf_counter() - start
    return f


# --- the choice -------------------------------------------------------------------------------


@dataclass
class Candidate:
    name: str
    predicted: float
    #: Estimated seconds (``Model.seconds`` of the work; 0 for no SSS).
    cost: float
    #: Why it could not be chosen (missing passes, skipped by its plan...), None when it could.
    excluded: str | None = None
    #: Work estimate: pixels x samples per pixel (0 for no SSS).
    work: float = 0.0
    #: The error its fit measured against Cycles on the material's held-out blocks (None: not measured).
    measured: float | None = None
    #: For a rung of a technique the fit measured: that measurement times the rung's predicted error
    #: over the technique's predicted error at its default (the fit measures the default only).
    scaled: float | None = None

    @property
    def technique(self) -> str:
        return NONE if self.name == NONE else technique_of(self.name)

    @property
    def is_rung(self) -> bool:
        """True for a rung other than its technique's default (a quality, or the energy stage off)."""
        return self.name not in (NONE, self.technique)


@dataclass
class MaterialChoice:
    """One material's features, its candidates and the one chosen, with the reason."""

    material: MaterialSSS
    features: Features
    candidates: list[Candidate]
    chosen: str
    reason: str
    #: Kept for the callers that read a plan's materials (``Plan.applied``-like).
    warning: str | None = None
    #: Rungs of the candidate techniques the model has no coefficients for (not candidates).
    unmodelled: list[str] = field(default_factory=list)

    @property
    def applied(self) -> bool:
        return self.chosen != NONE


@dataclass
class AutoPlan:
    """``choose``'s result; reads like a ``core.pipeline.plan.Plan`` for the command line."""

    shape: tuple[int, int]
    max_error: float
    choices: list[MaterialChoice]
    #: The plans of the chosen candidates (a technique, or a rung of it: ``technique option=value``),
    #: each restricted to the materials that chose it.
    plans: dict[str, Plan]
    model: Model
    skipped_materials: list[str] = field(default_factory=list)
    technique: str = AUTO
    nonfinite_pixels: int = 0
    overflow_pixels: int = 0
    negative_pixels: int = 0
    #: As ``Plan``'s: Material Index pixels that are not whole numbers, and one of their values.
    fractional_index_pixels: int = 0
    fractional_index_value: float | None = None
    #: Whether the rungs of the techniques' quality ladders were candidates (``choose(rungs=...)``).
    rungs: bool = False

    @property
    def scattering(self) -> list[MaterialChoice]:
        return self.choices

    @property
    def index_warning(self) -> str | None:
        """What a Material Index pass holding values that are not whole numbers means, or None."""
        return index_warning(self.fractional_index_pixels, self.fractional_index_value)

    @property
    def applied(self) -> list[MaterialChoice]:
        return [c for c in self.choices if c.applied]

    @property
    def chosen(self) -> dict[str, str]:
        """{material name: chosen candidate}, what ``choose(keep=...)`` takes on the next frames."""
        return {c.features.name: c.chosen for c in self.choices}

    def to_dict(self) -> dict:
        """The plan as JSON-ready data: per material its features, every candidate (predicted and
        measured error, cost, why excluded) and the choice with its reason (``explain`` in words)."""
        h, w = self.shape
        return {
            "size": [w, h],
            "max_error": self.max_error,
            "rungs": self.rungs,
            "model": self.model.command or "given",
            "skipped": list(self.skipped_materials),
            "materials": [
                {
                    "material": c.features.name,
                    "index": c.features.index,
                    "chosen": c.chosen,
                    "reason": c.reason,
                    "warning": c.warning,
                    "features": dataclasses.asdict(c.features),
                    "candidates": [dataclasses.asdict(k) for k in c.candidates],
                }
                for c in self.choices
            ],
        }

    def explain(self) -> str:
        h, w = self.shape
        lines = [
            f"auto on {w}x{h} pixels: per material, the cheapest technique"
            f"{' or rung of its quality ladder' if self.rungs else ' at its default quality'} whose predicted"
            " error (measured, where the material's fit measured two or more techniques) is within"
            f" {100 * self.max_error:.0f} % of the best"
            f" (model: {self.model.command or 'given'})"
        ]
        if not self.choices:
            lines.append("  no material in the scene description scatters light on screen: nothing to do")
        if self.index_warning:
            lines.append(f"  warning: {self.index_warning}")
        for line in self.skipped_materials:
            lines.append(f"  {line}")
        for c in self.choices:
            f = c.features
            lines.append(f"  material {f.name!r} (pass index {f.index}, {f.pixels} pixels): {c.chosen}")
            fp = " / ".join(f"{v:.3g}" for v in f.footprint_px)
            lines.append(f"    footprint d R/G/B {fp} px at the median depth")
            lines.append(
                f"    diffusion D {f.diffusion:.4f} (how much spreading the visible light over 2.5 d changes it),"
                f" wide W {f.wide:.4f} (the part with a footprint of {WIDE_PX:g} px or more)"
            )
            lines.append(f"    energy V {f.view:.4f} (what the techniques' energy convention changes)")
            thick = "" if f.thickness_over_d is None else f", median thickness {f.thickness_over_d:.3g} d"
            lines.append(
                f"    light from behind B {f.back:.4f} ({100 * f.back_share:.1f} % of the visible diffuse light{thick})"
            )
            if f.fitted:
                lines.append(f"    fitted for {', '.join(f.fitted)}; energy its fitted gain corrects G {f.energy:.4f}")
            lines += [f"    {n}" for n in f.notes]
            if not any(k.measured is not None and k.excluded is None for k in c.candidates):
                lines.append(
                    "    no fit measured two or more techniques here: the errors are predicted (calibrate, or"
                    " Fit to Cycles in the panel, measures them against Cycles)"
                )
            ok = sorted((k for k in c.candidates if not k.excluded), key=lambda k: (k.cost, k.name))
            width = max([len(k.name) for k in ok] + [9])
            for cand in ok:
                seen = ""
                if cand.measured is not None:
                    seen = f", measured {cand.measured:.4f} (its fit, held out)"
                elif cand.scaled is not None:
                    seen = f", {cand.scaled:.4f} from {cand.technique}'s measured error x the predicted ratio"
                lines.append(
                    f"    {cand.name:{width}s} predicted error {cand.predicted:.4f}{seen}, estimated"
                    f" {1000 * cand.cost:.3g} ms ({cand.work:.3g} pixel-samples)"
                )
            # Excluded candidates: one line per technique and reason.
            grouped: dict[tuple[str, str], list[str]] = {}
            for cand in c.candidates:
                if cand.excluded:
                    grouped.setdefault((cand.technique, cand.excluded), []).append(cand.name)
            for (technique, why), names in grouped.items():
                if names == [technique]:
                    lines.append(f"    {technique:{width}s} not a candidate: {why}")
                else:
                    lines.append(f"    {technique} ({len(names)} rungs: {', '.join(names)}) not candidates: {why}")
            if c.unmodelled:
                lines.append(
                    f"    not candidates, the auto model has no coefficients for them: {', '.join(c.unmodelled)}"
                )
            lines.append(f"    => {c.chosen}: {c.reason}")
            if c.warning:
                lines.append(f"    warning: {c.warning}")
        return "\n".join(lines)


def measured_errors(material: MaterialSSS) -> dict[str, float]:
    """{technique: the held-out error its fit measured against Cycles} for the techniques the
    material carries a fit for (``core/study/fit.py``'s provenance, ``info["heldout_after"]``), when two or
    more were measured on renders of the same sample count (``samples`` in their provenance; the
    fits of one ``calibrate`` run share one render). {} otherwise: measurements against renders of
    different noise are not compared."""
    found: dict[str, tuple] = {}
    for technique, params in (material.fit or {}).items():
        if not fitted(material.fit, technique) or fitted(material.fit, technique).get(OFF):
            continue  # no fit, or switched off (not a candidate)
        info = params.get(INFO) or {}
        try:
            err = float(info["heldout_after"])
        except (KeyError, TypeError, ValueError):
            continue
        if math.isfinite(err) and err >= 0:
            found[technique] = (err, info.get("samples"))
    renders = {samples for _, samples in found.values()}
    if len(found) < 2 or len(renders) != 1:
        return {}
    return {t: v[0] for t, v in found.items()}


def _work(technique: str, material: MaterialSSS, pixels: int, lights: int, mapping, options=None) -> float:
    """pixels x (samples per pixel + one per light when the technique adds light from behind), with
    ``options`` (a rung's: ``variants``) over the material's parameters."""
    return _works(technique, material, pixels, lights, mapping, [options or {}])[0]


def _works(technique: str, material: MaterialSSS, pixels: int, lights: int, mapping, runs) -> list[float]:
    """``_work`` of each options of ``runs``, the material's parameters read once."""
    spec = get_spec(technique)
    params = technique_params(material, technique, mapping=mapping)
    return [pixels * float(spec.samples_per_pixel({**params, **options}, lights)) for options in runs]


def choose(
    passes: Passes,
    scene: SceneDescription,
    *,
    max_error: float = DEFAULT_MAX_ERROR,
    model: Model | None = None,
    techniques=None,
    albedo_mode: str = "post",
    mapping=None,
    keep=None,
    rungs: bool = False,
) -> AutoPlan:
    """Per scattering material on screen, the technique and quality to run (or none), and why.

    The candidates are no SSS and each technique at its default quality; with ``rungs``, each of
    the technique's runs in ``variants`` (its quality ladder's rungs, and without its energy stage)
    that the model has coefficients for (cheaper, and further from the best: ``DEFAULT_MAX_ERROR``
    says by how much on the fidelity suite). ``techniques``: the
    techniques whose runs are candidates (default: every registered technique); one whose passes
    are missing is not a candidate (said in the plan). ``max_error`` >= 0: how much worse than the
    best predicted error (relative) a cheaper choice may be. ``keep``: {material name: candidate}
    chosen before (on the first frame of a sequence): kept where it can still run, so that a
    material's look does not switch from frame to frame.
    """
    if not (isinstance(max_error, (int, float)) and math.isfinite(max_error) and max_error >= 0):
        raise InputError(f"max_error: expected a number >= 0 (0.05 = within 5 % of the best), got {max_error!r}")
    model = model or load_model()
    # Every registered technique is a candidate (a new one too: without coefficients it is listed
    # as not a candidate until the model is learnt again with it).
    names = [get_spec(t).name for t in techniques] if techniques is not None else list(TECHNIQUES)
    # Only the chosen runs are planned (below); a candidate needs its passes and its work.
    missing: dict[str, str] = {}
    for t in names:
        lacking = [p for p in required_passes(t, scene.thickness_aov) if p not in passes]
        if lacking:
            missing[t] = f"missing pass(es) {', '.join(lacking)}"
    auto = AutoPlan(
        shape=passes.shape, max_error=float(max_error), choices=[], plans={}, model=model, rungs=bool(rungs)
    )
    auto.fractional_index_pixels, auto.fractional_index_value = fractional_indices(passes)
    scene = read_scene(passes, scene)  # inputs linked to textures: their medians on screen
    chosen_by: dict[str, set[int]] = {}
    shared = _Shared(passes, scene)
    for material in scene.materials:
        name = material.name or str(material.index)
        if not material.scatters:
            auto.skipped_materials.append(f"material {name!r}: does not scatter light: left as it is")
            continue
        f = features(passes, scene, material, _shared=shared)
        if not f.pixels:
            auto.skipped_materials.append(f"material {name!r}: no pixel on screen: left as it is")
            continue
        cands = [Candidate(NONE, model.predict(NONE, f), 0.0)]
        unmodelled = []
        for t in names:
            if not get_spec(t).auto:
                cands.append(Candidate(t, math.nan, math.nan, "its spec keeps it out of auto (auto=False)"))
                continue
            every = variants(t)
            if not rungs:
                every = {n: o for n, o in every.items() if n == t}
            runs = {n: o for n, o in every.items() if n in model.coefficients}
            if not runs:
                cands.append(Candidate(t, math.nan, math.nan, "the auto model has no coefficients for it"))
                continue
            unmodelled += [n for n in every if n not in runs]
            if t in missing:
                cands += [Candidate(n, math.nan, math.nan, f"its passes are missing ({missing[t]})") for n in runs]
                continue
            if fitted(material.fit, t).get(OFF):
                why = "calibrate measured it worse than no SSS on this material (its fit switched it off)"
                cands += [Candidate(n, math.nan, math.nan, why) for n in runs]
                continue
            works = _works(t, material, f.pixels, len(scene.lights), mapping, list(runs.values()))
            for (n, options), work in zip(runs.items(), works, strict=True):
                if t in f.fitted and options.get("energy") == ENERGY_OFF["energy"]:
                    # The fit (core/study/fit.py) runs the technique with its energy stage: the fitted gain
                    # holds that stage's energy, and without it the gain is wrong.
                    why = f"the material's fit for {t} was made with its energy stage on"
                    cands.append(Candidate(n, math.nan, math.nan, why))
                    continue
                cands.append(Candidate(n, model.predict(n, f), model.seconds(n, work), work=work))
        pick, reason, score = _pick(cands, f, measured_errors(material), max_error)
        kept = (keep or {}).get(f.name)
        if kept is not None and kept != pick.name:
            held = next((c for c in cands if c.name == kept and c.excluded is None), None)
            if held is not None:
                reason = f"kept from the first frame (this frame alone would choose {pick.name}: {reason})"
                pick = held
        if pick.name != NONE:
            chosen_by.setdefault(pick.name, set()).add(material.index)
        auto.choices.append(MaterialChoice(material, f, cands, pick.name, reason, unmodelled=unmodelled))
    for run, indices in chosen_by.items():
        t = technique_of(run)
        p = plan(passes, scene, t, albedo_mode=albedo_mode, mapping=mapping, **options_of(run))
        for mp in p.materials:
            if mp.material.index not in indices:
                if mp.skip is None:
                    mp.skip = "auto chose another technique for it"
                continue
            choice = next(c for c in auto.choices if c.material.index == mp.material.index)
            choice.warning = mp.warning
            if mp.skip:
                choice.reason += f"; {run} leaves it as it is: {mp.skip}"
        auto.plans[run] = p
    return auto


def _pick(cands: list[Candidate], f: Features, measured: dict, max_error: float) -> tuple[Candidate, str, dict]:
    """The candidate ``choose`` takes among ``cands`` (excluding, in place, those a measured choice
    cannot compare), the reason in words, and the error each was judged by."""
    runnable = [c for c in cands if c.excluded is None]
    # With two or more runnable techniques measured by the material's fit, the measurements decide.
    what = "measured" if sum(c.name in measured for c in runnable) >= 2 else "predicted"
    default = {c.name: c for c in runnable}
    for c in cands:
        c.measured = measured.get(c.name)
        if what != "measured" or c.excluded is not None or c.measured is not None:
            continue
        own = default.get(c.technique)
        if c.technique in measured and own is not None:
            # A rung of a measured technique: the fit measured its default; the rung differs from it
            # as predicted.
            ratio = c.predicted / own.predicted if own.predicted > 0 else 1.0
            c.scaled = measured[c.technique] * ratio
        else:
            c.excluded = f"not measured by the material's fit (measured: {', '.join(sorted(measured))})"
    ok = [c for c in cands if c.excluded is None]
    # In measured mode every candidate left has its measurement or a rung's scaled one.
    score: dict[str, float] = {c.name: _judged(c) if what == "measured" else c.predicted for c in ok}
    best = min(ok, key=lambda c: score[c.name])
    limit = score[best.name] * (1.0 + max_error)
    within = [c for c in ok if score[c.name] <= limit + 1e-12]
    if what == "measured":
        # The measurement holds the fit render's noise, which brings every technique's measured
        # error closer to the best's: a cheaper technique must be within the margin of the best
        # measured one by its prediction too.
        within = [c for c in within if c.predicted <= best.predicted * (1.0 + max_error) + 1e-12]
    # The rungs of one technique run the same kernels with fewer samples or without a stage: their
    # costs rank reliably, and its cheapest rung within the margin stands for it. Between
    # techniques, estimated costs within COST_TOLERANCE count as equal and the lower error decides.
    finalists: dict[str, Candidate] = {}
    for c in within:
        held = finalists.get(c.technique)
        if held is None or (c.cost, score[c.name]) < (held.cost, score[held.name]):
            finalists[c.technique] = c
    cheapest = min(c.cost for c in finalists.values())
    alike = [c for c in finalists.values() if c.cost <= cheapest * (1.0 + COST_TOLERANCE) + 1e-12]
    pick = min(alike, key=lambda c: (score[c.name], c.cost))
    if pick is best:
        reason = f"the best {what} error ({score[best.name]:.4f})"
        if len(within) > 1:
            reason += " and the cheapest within the margin"
    else:
        reason = (
            f"cheapest within {100 * max_error:.0f} % of the best {what} error"
            f" ({best.name} {score[best.name]:.4f}); {what} {score[pick.name]:.4f}"
        )
    if len(alike) > 1:
        reason += f" (estimated costs within {100 * COST_TOLERANCE:.0f} % of the cheapest count as equal)"
    if pick.is_rung:
        reason += _rung_reason(pick, default.get(pick.technique), score, f)
    if what == "measured":
        reason += "; measured by its fit against Cycles on the material's held-out blocks"
        if pick.scaled is not None:
            reason += f" ({pick.technique} at its default quality; the rung's error scaled by the predicted ratio)"
    return pick, reason + _why(f, pick.name), score


def _judged(c: Candidate) -> float:
    """A candidate's measured error, or for a rung of a measured technique its scaled one."""
    value = c.measured if c.measured is not None else c.scaled
    assert value is not None, f"{c.name}: neither measured nor scaled"
    return value


def _rung_reason(pick: Candidate, own: Candidate | None, score: dict, f: Features) -> str:
    """Why a rung rather than its technique's default quality, in words."""
    options = options_of(pick.name)
    parts = []
    if options.get("energy") == ENERGY_OFF["energy"]:
        parts.append(f"the energy stage off (energy V {f.view:.4f}: the techniques' energy changes little here)")
    quality = {k: v for k, v in options.items() if k != "energy"}
    if quality:
        parts.append(" ".join(f"{k}={v}" for k, v in quality.items()) + f" instead of {pick.technique}'s default")
    text = f"; {' and '.join(parts)}"
    if own is None:
        return text + f" ({pick.technique}'s default is not a candidate)"
    if own.name not in score:
        return text
    return text + (
        f": estimated {1000 * pick.cost:.3g} ms against {1000 * own.cost:.3g} ms,"
        f" error {score[pick.name]:.4f} against {score[own.name]:.4f} at the default"
    )


def _why(f: Features, chosen: str) -> str:
    """What the features say, in words."""
    parts = []
    if f.diffusion < 0.01:
        parts.append("spreading its light over its footprint changes little")
    if f.back < 0.01:
        parts.append("little light from behind")
    elif f.back > f.diffusion:
        parts.append("light from behind outweighs the diffusion")
    return f" ({'; '.join(parts)})" if parts else ""


def apply_auto(passes: Passes, scene: SceneDescription, *, prepared: AutoPlan | None = None, **options) -> dict:
    """Run each material's chosen technique at its chosen quality; returns ``SSSLab.auto.Image`` and
    ``SSSLab.auto.SSS`` (as ``core.pipeline.apply.apply``: float32, Combined untouched outside the computed
    materials), or {} when no material scatters light on screen. ``options`` go to ``choose``."""
    auto = prepared or choose(passes, scene, **options)
    if not auto.choices:
        return {}
    name_image, name_sss = core_apply.layer_names(AUTO)
    if len(auto.plans) == 1:
        # One run chosen: its layers are auto's (Combined untouched outside the computed
        # materials, as below), without a second copy of the frame and a sum over it.
        ((run, p),) = auto.plans.items()
        t = p.spec.name
        layers = core_apply.apply(passes, scene, t, albedo_mode=p.albedo_mode, prepared=p)
        if layers:
            auto.nonfinite_pixels = p.nonfinite_pixels
            auto.overflow_pixels = p.overflow_pixels
            auto.negative_pixels = p.negative_pixels
            image, sss = (layers[n] for n in core_apply.layer_names(t))
            return {name_image: image, name_sss: sss}
        # Nothing computed: Combined as it is, below (its apply returns at once again).
    combined = passes["Combined"]
    image = np.array(combined, dtype=np.float32)
    sss = np.zeros(combined.shape[:2] + (3,), np.float32)
    nonfinite = overflow = negative = 0
    for p in auto.plans.values():
        t = p.spec.name
        layers = core_apply.apply(passes, scene, t, albedo_mode=p.albedo_mode, prepared=p)
        if layers:
            sss += layers[core_apply.layer_names(t)[1]]
        nonfinite += p.nonfinite_pixels
        overflow += p.overflow_pixels
        negative += p.negative_pixels
    image[..., :3] += sss
    # Each run kept its own result non-negative; their sum over several runs' pixels adds nothing
    # negative to a pixel no run touched, and each pixel is one material's (one run's).
    auto.nonfinite_pixels = nonfinite
    auto.overflow_pixels = overflow
    auto.negative_pixels = negative
    return {name_image: image, name_sss: sss}


# --- learning the model -----------------------------------------------------------------------


def _nnls(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Non-negative weighted least squares with a few unknowns: every subset of active
    coefficients solved exactly, the feasible one with the smallest residual kept."""
    sw = np.sqrt(w)
    xw, yw = x * sw[:, None], y * sw
    best, best_r = np.zeros(x.shape[1]), float(np.sum(yw**2))
    n = x.shape[1]
    for bits in range(1, 2**n):
        cols = [i for i in range(n) if bits >> i & 1]
        coef, *_ = np.linalg.lstsq(xw[:, cols], yw, rcond=None)
        if np.any(coef < 0):
            continue
        full = np.zeros(n)
        full[cols] = coef
        r = float(np.sum((xw @ full - yw) ** 2))
        if r < best_r:
            best, best_r = full, r
    return best


def train(samples, *, timings=(), trained_on=(), command: str = "") -> Model:
    """Learn the coefficients from measured errors.

    ``samples``: (Features, {candidate: relative error}) pairs, one per material of a scene, the
    candidates including ``NONE`` (a technique at its default quality, or one of its rungs,
    ``variants``: each learnt from its own measurements). Each candidate's error^2 is fitted to
    (D^2, B^2, 1, W^2, V^2) by non-negative least squares, each material weighted by 1 / its
    no-SSS error^2 so that every material counts alike whatever its scene's error level. The
    energy term is not learnt (no SSS always keeps it, a fitted technique removes it): it is
    subtracted from the measured error^2 first. ``timings``: (candidate, work, seconds)
    measurements; each candidate's rate is the median of seconds / work."""
    by_candidate: dict[str, list] = {}
    for f, errors in samples:
        none = errors.get(NONE)
        if none is None or not math.isfinite(none) or none <= 0:
            continue
        for t, err in errors.items():
            if err is None or not math.isfinite(err):
                continue
            e2 = err**2 - (0.0 if t != NONE and technique_of(t) in f.fitted else f.energy**2)
            by_candidate.setdefault(t, []).append(
                (f.diffusion**2, f.back**2, f.wide**2, f.view**2, max(e2, 0.0), 1.0 / none**2)
            )
    if NONE not in by_candidate:
        raise InputError("train: no sample with a finite no-SSS error: nothing to learn from")
    coefficients = {}
    for t, rows in by_candidate.items():
        a = np.asarray(rows, np.float64)
        x = np.column_stack([a[:, 0], a[:, 1], np.ones(len(a)), a[:, 2], a[:, 3]])
        coefficients[t] = tuple(float(v) for v in _nnls(x, a[:, 4], a[:, 5]))
    rates: dict[str, list] = {}
    for t, work, seconds in timings:
        if work > 0 and seconds > 0 and math.isfinite(seconds):
            rates.setdefault(t, []).append(seconds / work)
    seconds_per_work = {t: float(np.median(v)) for t, v in rates.items()}
    return Model(coefficients, tuple(trained_on), command, seconds_per_work)


def save_model(model: Model, path: str = MODEL_PATH) -> None:
    from ..base.files import write_text

    write_text(path, json.dumps(model.to_dict(), indent=2) + "\n")
