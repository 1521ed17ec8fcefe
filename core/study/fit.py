"""Fit each subsurface material's technique parameters to a Cycles random-walk render.

What is left once the techniques are correct is mostly per material: energy per channel (light
entering through surfaces the camera does not see, Cycles' albedo inversion against Lambert)
and light from behind (docs/references.md §9). Given the passes, their scene description, a
random-walk render of the same view (a few dozen samples are enough) and the Material Index
mask, ``fit_scene`` finds per material and technique the parameters of ``core/pipeline/fit_params.py``
that minimize the squared error over the material's pixels:

    model = Combined - A E + g_c S_c(k) + s_c T_c(f_c)      (per channel c)

with S(k) the technique's albedo-applied light with d times k (Burley, SSSS, the combined
technique's diffusion), g the per-channel gain, and for the combined technique T(f) its light
from behind with the transmittance's length per channel times f_c and the scale s_c
(``core/techniques/combined/technique.py``);
STA: Combined + s x its term at scale 1.

Robust to Monte Carlo noise (docs/references.md §8):
- both images are averaged over ``box`` x ``box`` blocks; only blocks entirely inside the
  material count (the noise of a block mean falls with its pixel count, the smooth SSS
  differences stay); a material with fewer than ``MIN_BLOCKS`` such blocks is fitted on smaller
  ones (halving the size, down to 2 x 2) before it is refused;
- the fit is judged by ``folds``-fold cross-validation: the blocks are dealt at random (fixed
  seed) into ``FOLDS`` folds, and each fold is predicted by the fit made on the other folds, so
  that every block is held out once and judges the fit; a fit whose held-out error over all
  folds is not below the unfitted one over-fits the noise (or the model cannot explain the
  material) and is rejected, the material left unchanged; a fit that holds is made again on
  every block, which gives the values kept;
- the parameters are bounded (``fit_params.PARAMETERS``, the light from behind's scale at most
  ``TRANSMISSION_SCALE_MAX``; k and f searched on a grid of
  factors of sqrt(2) from 1/4 to 4, coarse to fine (``_search``, ``_Lengths``), then k refined
  between its neighbours) and pulled towards
  "no change" by a ridge term of weight ``regularization`` relative to each basis' energy, so
  that a direction the pixels barely see (a channel with no light, no light from behind) stays
  at its default.
For each k (one technique run) and each f the problem is linear in (g, s): its normal equations
come from a few dot products per channel, so the whole grid costs little more than the
technique runs. Each k runs only the technique's light transport (``_Diffusion``: its energy
stage does not depend on d and is applied in closed form), with the compiled kernels on one
thread (``core.compute.backend.one_thread``). Burley's adaptive sample counts (the diffusion of
Burley and the combined technique) are planned once, from the material's own d, for every k: the
plan apply gives the fitted material (``plan_d_su``, ``core.pipeline.mapping.technique_params``),
so the error does not move in steps as k changes the counts.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..base.errors import InputError
from ..compute import backend
from ..optics.energy import apply_energy, energy_inputs
from ..pipeline import apply as core_apply
from ..pipeline import mapping as _mapping
from ..pipeline.call import call_technique
from ..pipeline.fit_params import FIT_PARAMETERS, INFO, OFF, PARAMETERS
from ..pipeline.plan import index_map, plan
from ..scene.inputs import read_scene, weight_map
from ..scene.scene import MaterialSSS, SceneDescription
from ..techniques.combined.technique import light_from_behind
from ..techniques.registry import get_spec
from .metrics import box_downsample

#: Search grid for d's scale k and the transmission's per-channel factors f: sqrt(2) steps, 1/4..4.
GRID = tuple(2.0 ** (i / 2.0) for i in range(-4, 5))
#: Block size (pixels) of the means the fit compares: 2 x 2, the fidelity suite's error measure's
#: (core/study/metrics.py), so that the pixels it judges near a material's edges count as well. On the
#: suite (``python -m benchmarks.fit --box N``) 2, 4 and 8 gave on the diffusion scenes a median
#: removed of 59.6 / 59.6 / 57.5 % on frame A and 54.3 / 53.9 / 53.9 % on frame B, on the back-lit
#: ones 89.5 / 89.2 / 89.2 % and 80.5 / 74.8 / 74.8 % (docs/references.md §16).
BOX = 2
#: Fewest blocks inside a material for a fit (with 4 folds: each fit on 24, checked on 8).
MIN_BLOCKS = 32
#: Folds of the cross-validation that judges a fit (module docstring). One random quarter of the
#: blocks held out refused real gains on materials of few blocks, where which blocks fall in the
#: quarter decides (``benchmarks.fit``; docs/references.md §16); four folds judge with every block
#: at the cost of four more searches (the technique runs and transmissions are shared).
FOLDS = 4
#: The largest transmission scale the fit gives (``fit_params.PARAMETERS`` accepts up to 16 set by
#: hand, or stored by a fit made before): the gains and d's scale are fitted within a factor 4
#: either way, and so is the light from behind's scale. Within 16, on diffusion scenes with little
#: light from behind (its basis weakly determined) the scale ran to 16, the basis standing in for
#: light it does not model, and the fit of frame A failed on frame B where that light is strong
#: (the head lit from behind: the fitted combined technique 1.664 against 0.734 unfitted); within 4
#: 0.512, with the suite's medians the same (``benchmarks.fit``, docs/references.md §16).
TRANSMISSION_SCALE_MAX = 4.0


#: The render a fit stands in for: Cycles random walk of the same view at this many samples (each
#: of the fidelity suite's two converged reference renders, ``benchmarks/fit.py``).
REFERENCE_SAMPLES = 1024
#: The most samples ``calibrate`` renders by default for the fits the held-out check refused (the
#: first render's and the second's together): the top of the 16-64 samples the fit is measured on
#: (``benchmarks/fit.py``).
MAX_SAMPLES = 64
#: The share of that render's time a fit may take (its passes, renders and fitting together): the
#: budget within which ``more_samples`` adds samples for fits the held-out check refused. The fit's
#: goal is 10 %; a point less leaves room for the estimate's error (on the fidelity suite the
#: measured share came out 0.3 to 0.5 points above the estimate, ``benchmarks/fit.py``).
BUDGET = 0.09


def render_time_split(render_s: float, samples: int, pilot_s: float, pilot_samples: int = 1) -> tuple | None:
    """(fixed seconds, seconds per sample) of a view's Cycles render, from two renders of it:
    ``samples`` samples in ``render_s`` seconds and ``pilot_samples`` (fewer) in ``pilot_s``. A
    render's time is a fixed part (synchronising the scene, building its BVH, starting the device)
    plus a part per sample; one render cannot tell them apart, and on a small view the fixed part
    is a large share of a short render. None when the two give no positive time per sample (too
    noisy to tell) or are not such a pair."""
    if not (isinstance(samples, int) and isinstance(pilot_samples, int) and 0 < pilot_samples < samples):
        return None
    if not all(isinstance(v, (int, float)) and math.isfinite(v) and v >= 0 for v in (render_s, pilot_s)):
        return None
    per_sample = (render_s - pilot_s) / (samples - pilot_samples)
    if not per_sample > 0:
        return None
    return max(pilot_s - pilot_samples * per_sample, 0.0), per_sample


def more_samples(
    *,
    samples: int,
    max_samples: int,
    spent_s: float,
    render_s: float,
    pilot_s: float,
    fit_s: float,
    budget: float = BUDGET,
) -> tuple[int, str]:
    """How many samples to render again for the fits the held-out check refused (those materials
    are then fitted again on the two renders' mean), and why: ``max_samples`` - ``samples`` when
    the estimated total stays within ``budget`` of the render the fit stands in for (a
    ``REFERENCE_SAMPLES``-sample render of the view, from ``render_time_split`` of the fit's render
    and a one-sample pilot), else 0. ``spent_s``: the seconds spent so far (renders, passes, fit,
    the pilot); the new render is estimated as its fixed part plus its samples, the second fit as
    long as the first."""
    extra = max_samples - samples
    if extra <= 0:
        return 0, f"{samples} samples already (at most {max_samples})"
    split = render_time_split(render_s, samples, pilot_s)
    if split is None:
        return 0, "the renders' times give no estimate of a converged render's"
    fixed, per_sample = split
    reference = fixed + REFERENCE_SAMPLES * per_sample
    share = (spent_s + fixed + extra * per_sample + fit_s) / reference
    cost = f"{share:.1%} of a {REFERENCE_SAMPLES}-sample render (estimated {reference:.3g} s; budget {budget:.0%})"
    if share > budget:
        return 0, f"{extra} more samples would cost {cost}"
    return extra, f"{extra} more samples: in all {cost}"


def mean_render(first, first_samples: int, second, second_samples: int):
    """Two renders of one view averaged by their sample counts, in the first's dtype: what the fits
    the held-out check refused are made again on, after ``more_samples``."""
    total = first_samples + second_samples
    return (first * (first_samples / total) + second * (second_samples / total)).astype(first.dtype)


def refused_pairs(refused) -> set:
    """The (material name, technique) pairs of ``fit_scene``'s ``refused`` list: its ``only`` for
    the second fit."""
    return {(m, t) for m, t, _line in refused}


def after_second_fit(problems, refused, second_problems) -> list:
    """``problems`` (the first fit's lines) with the refusals of ``refused`` replaced by the second
    fit's lines ``second_problems``."""
    first = {line for _m, _t, line in refused}
    return [line for line in problems if line not in first] + list(second_problems)


def _fit_range(name: str) -> tuple[float, float]:
    """The bounds the fit gives the parameter ``name``: ``fit_params.PARAMETERS``' own, the light
    from behind's scale at most ``TRANSMISSION_SCALE_MAX``."""
    _, lo, hi = PARAMETERS[name]
    return lo, (min(hi, TRANSMISSION_SCALE_MAX) if name == "transmission_scale" else hi)


def _cross_validated(fold: np.ndarray, predict) -> np.ndarray:
    """Each block's prediction by the fit made without its fold: ``predict(blocks)`` fits on the
    blocks ``blocks`` (bool, N) and returns the model's values on every block (N, ...)."""
    folds = [fold == j for j in range(int(fold.max()) + 1)]
    models = [predict(~held) for held in folds]
    out = np.empty_like(models[0])
    for held, model in zip(folds, models, strict=True):
        out[held] = model[held]
    return out


#: Below this share of the target's energy a basis (light from behind, STA's term) counts as
#: absent on the material: its parameters keep their defaults.
_ABSENT = 1e-6
#: Relative difference allowed between the energy stage run on a light and its affine form
#: G light + B (``_Diffusion``): the two differ by the order of a handful of float32 products and
#: sums (each within 2^-24 relatively), far below it; a stage that is not affine differs by more.
_AFFINE_TOL = 1e-5


class FitError(InputError):
    """A material cannot be fitted; the message names it and says why (it is left unchanged)."""


class HeldOutError(FitError):
    """A fit that does not hold on the held-out blocks: the render it was made on may be too noisy
    for it (``calibrate`` renders more samples for it, ``blender/calibrate.py``)."""

    def __init__(self, message: str, material: str, technique: str):
        super().__init__(message)
        self.material, self.technique = material, technique


@dataclass
class FitResult:
    """One material's fit for one technique."""

    material: str
    index: int
    technique: str
    #: The fitted values (``core/pipeline/fit_params.py`` names) plus ``info`` (provenance).
    params: dict
    #: Relative RMSE (block means, see the module docstring) before (the unfitted mapping) and
    #: after the fit: on every block with the values kept (fitted on every block), and on each
    #: block held out, predicted by the fit on the other folds (cross-validation).
    train_before: float
    train_after: float
    heldout_before: float
    heldout_after: float
    blocks: int
    heldout_blocks: int
    folds: int = FOLDS
    #: The error with no SSS on the same blocks: a fit whose held-out error is not below it switches
    #: the technique off on the material (``fit_params.OFF``).
    heldout_none: float = math.nan
    at_bounds: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    seconds: float = 0.0

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def summary(self) -> str:
        values = ", ".join(f"{k}={_fmt(v)}" for k, v in self.params.items() if k != INFO)
        line = (
            f"{self.material!r} {self.technique}: {values}; held-out error {self.heldout_before:.4g} ->"
            f" {self.heldout_after:.4g} ({self.blocks} blocks, each held out once in {self.folds} folds,"
            f" {self.seconds:.1f} s)"
        )
        if self.at_bounds:
            line += f"; at its bound: {', '.join(self.at_bounds)}"
        return line + "".join(f"; {n}" for n in self.notes)


def _fmt(v) -> str:
    if isinstance(v, (tuple, list)):
        return "(" + ", ".join(f"{x:.4g}" for x in v) + ")"
    return f"{v:.4g}"


#: The least Subsurface Weight of a block the fit reads (core/scene/inputs.py: Cycles' mix).
MIN_WEIGHT = 0.1


def _weight_image(material: MaterialSSS, passes, mask: np.ndarray) -> np.ndarray | None:
    """The material's Subsurface Weight per pixel (its AOV where it is linked, else its number),
    float64 (H, W); None when it is 1 everywhere (no mix to undo)."""
    w = weight_map(material, passes, mask)
    if w is None:
        return None if material.subsurface_weight >= 1.0 else np.full(mask.shape, material.subsurface_weight)
    return w.astype(np.float64)


def _rel_rmse(residual: np.ndarray, target: np.ndarray) -> float:
    mean = float(np.mean(target))
    if residual.size == 0 or mean <= 0:
        return math.nan
    return float(np.sqrt(np.mean(residual * residual))) / mean


def _blocks(image: np.ndarray, keep: np.ndarray, box: int) -> np.ndarray:
    """(N, 3) float64 block means of ``image`` (H, W, 3) over the blocks ``keep`` (h, w)."""
    return box_downsample(np.asarray(image[..., :3], np.float64), box)[keep]


def _material_mask(passes, material: MaterialSSS, reference: np.ndarray) -> np.ndarray:
    index = index_map(passes)
    ok = index == material.index
    for name in ("Combined", "Diffuse Color"):
        ok &= core_apply.finite(passes[name][..., :3])
    ok &= core_apply.finite(reference[..., :3])
    return ok


def _check_inputs(passes, scene: SceneDescription, reference, technique: str) -> np.ndarray:
    if technique not in FIT_PARAMETERS:
        raise FitError(f"fit: no fit exists for technique {technique!r}; expected one of: {', '.join(FIT_PARAMETERS)}")
    if not isinstance(scene, SceneDescription):
        raise FitError(f"scene: expected a SceneDescription, got {type(scene).__name__}")
    ref = np.asarray(reference, np.float32)
    if ref.ndim != 3 or ref.shape[2] < 3 or ref.shape[:2] != passes.shape:
        raise FitError(
            f"reference: expected an image of the passes' size {passes.shape[1]}x{passes.shape[0]} with RGB,"
            f" got shape {ref.shape}"
        )
    return ref


def block_folds(count: int, *, folds: int, seed: int) -> np.ndarray:
    """The fold (0 .. ``folds`` - 1) of each of ``count`` blocks (in row-major order of the
    material's blocks): a random permutation drawn with ``seed``, dealt out in turn, so that the
    folds differ in size by one block at most and every block is held out exactly once."""
    fold = np.empty(count, np.int64)
    fold[np.random.default_rng(seed).permutation(count)] = np.arange(count) % folds
    return fold


@backend.one_thread()
def fit_material(
    passes,
    scene: SceneDescription,
    reference,
    material: MaterialSSS,
    technique: str,
    *,
    box: int = BOX,
    folds: int = FOLDS,
    seed: int = 0,
    regularization: float = 0.05,
    samples: int | None = None,
    heldout_check: bool = True,
) -> FitResult:
    """Fit ``technique``'s parameters of ``material`` (its pass index on ``passes``) to
    ``reference`` (H, W, 3 or 4, the Cycles render of the same view). Raises FitError with one
    line naming the material and the reason when it cannot be fitted: too few pixels, no bake
    distance for the combined technique, a fit that does not converge or does not hold on the
    held-out blocks (``folds``-fold cross-validation, see the module docstring). ``samples``: the
    reference's sample count, kept in the provenance. ``heldout_check=False`` keeps a fit that
    does not hold (the values fitted on every block, with a note saying so), to measure what the
    check refuses against a converged reference (``benchmarks.fit --keep-refused``); ``calibrate``
    never does."""
    start = time.perf_counter()
    ref = _check_inputs(passes, scene, reference, technique)
    if isinstance(folds, bool) or not isinstance(folds, (int, np.integer)) or not 2 <= folds <= MIN_BLOCKS // 2:
        raise FitError(f"folds: expected a whole number from 2 to {MIN_BLOCKS // 2}, got {folds!r}")
    name = material.name or str(material.index)
    if not material.scatters:
        raise FitError(f"material {name!r}: no subsurface scattering (Subsurface Weight, Radius or Scale is 0)")
    mask = _material_mask(passes, material, ref)
    pixels = int(mask.sum())
    keep = box_downsample(mask.astype(np.float64), box) >= 1.0
    count = int(keep.sum())
    # A small material: smaller blocks (down to 2 x 2, the error measure's) rather than no fit;
    # their means are noisier, which the held-out blocks still judge.
    first = (box, count)
    while count < MIN_BLOCKS and box > 2:
        box = max(box // 2, 2)
        keep = box_downsample(mask.astype(np.float64), box) >= 1.0
        count = int(keep.sum())
    if count < MIN_BLOCKS:
        raise FitError(
            f"material {name!r} covers {pixels} pixels, {first[1]} blocks of {first[0]}x{first[0]} inside it"
            f" ({count} of {box}x{box}): too few to fit (at least {MIN_BLOCKS} needed; render larger or move the"
            " camera closer); left unchanged"
        )
    # Cycles mixes (1 - w) diffuse + w subsurface at each pixel, and apply mixes the technique's
    # light the same way (core/pipeline/apply.py): the fit matches the technique's own light to what
    # the reference shows of it, on the blocks where at least MIN_WEIGHT of the surface scatters.
    weight = _weight_image(material, passes, mask)
    if weight is not None:
        keep = keep & (box_downsample(weight, box) >= MIN_WEIGHT)
        count = int(keep.sum())
        if count < MIN_BLOCKS:
            raise FitError(
                f"material {name!r}: only {count} blocks of {box}x{box} have a Subsurface Weight of at least"
                f" {MIN_WEIGHT} (at least {MIN_BLOCKS} needed): too little of it scatters to fit; left unchanged"
            )
        w = _blocks(np.repeat(weight[..., None], 3, axis=2), keep, box)
    else:
        w = None
    plain = dataclasses.replace(material, fit={})
    single = dataclasses.replace(scene, materials=(plain,))
    fold = block_folds(count, folds=folds, seed=seed)
    every = np.ones(count, bool)

    combined_rgb = passes["Combined"][..., :3]
    target = _blocks(ref, keep, box)
    spec = get_spec(technique)
    if not spec.scatters:  # it only adds light (STA): its scale is what there is to fit
        base = _blocks(combined_rgb, keep, box)
        layers = core_apply.apply(passes, single, spec, scale=1.0)
        basis = _blocks(layers[core_apply.layer_names(spec.name)[1]], keep, box)
        # STA's basis is apply's layer: the weight's mix is in it already.
        return _finish_sta(
            material, name, base, basis, target, fold, regularization, samples, start, pixels, heldout_check
        )

    albedo = core_apply.clean(passes["Diffuse Color"])
    original = albedo * (core_apply.clean(passes["Diffuse Direct"]) + core_apply.clean(passes["Diffuse Indirect"]))
    rest = _blocks(combined_rgb - original, keep, box)
    y = target - rest
    held = _blocks(original, keep, box)  # no SSS: the diffuse light the passes hold
    if w is not None:  # apply gives held + w (light - held): the light the reference shows
        y = held + (y - held) / w
    params0 = _mapping.technique_params(plain, technique)

    # Light from behind (combined only): E_back per channel and slab thickness, at full size.
    transmissions = None
    notes = []
    if spec.adds_light:
        distance = float(params0.get("thickness_distance_su") or 0.0)
        if distance <= 0:
            raise FitError(
                f"material {name!r}: its thickness map has no bake distance, so the light from behind cannot be"
                " fitted (bake thickness with SSS Lab first); left unchanged"
            )
    diffusion = _Diffusion(passes, single, spec, keep, box)
    if spec.adds_light:
        # The combined technique's light from behind exactly as it computes it (core/techniques/combined/technique.py:
        # the material's medium, exit weight, entry and lateral spread; what does not depend on the
        # length once), at scale 1 with each channel's length times 2^(q/2) (``_Transmissions``).
        back, d_tr0 = light_from_behind(diffusion.arguments)
        if back.lit.any():
            transmissions = _Transmissions(back, d_tr0, keep, box)
            # Absent: its energy over the whole grid of lengths (estimated from the first three)
            # is at most _ABSENT of the target's.
            first3 = _Lengths(transmissions).start()
            energy = len(GRID) * float(np.mean(np.sum(first3**2, axis=(1, 2))))
            if energy <= _ABSENT * float(np.sum(y**2)):
                transmissions = None
        if transmissions is None:
            notes.append("no light from behind on its pixels: transmission left at its defaults")

    def fit_on(blocks: np.ndarray) -> _Fitted:
        """The fit's search on ``blocks`` (k coarse to fine; for the combined technique the
        lengths of the light from behind coarse to fine per channel, ``_Lengths``, with k searched
        again on each new set of lengths: its technique runs are kept, only solves)."""
        lengths = _Lengths(transmissions) if transmissions is not None else None
        trans = lengths.start() if lengths is not None else None
        while True:
            solver = _Solver(y, blocks, trans, regularization, lengths.exponents() if lengths else None)
            evaluated: dict[float, tuple] = {}

            def evaluate(k: float, solver=solver, evaluated=evaluated):
                if k not in evaluated:
                    evaluated[k] = solver.solve(diffusion(k), k)
                return evaluated[k]

            best_k = _search(evaluate, evaluated)
            objective, g, s, f_idx, model = evaluated[best_k]
            if not (math.isfinite(objective) and np.all(np.isfinite(model)) and np.all(np.isfinite(g))):
                raise FitError(
                    f"material {name!r} {technique}: the fit did not converge (non-finite error); left unchanged"
                )
            if lengths is None or (more := lengths.next(f_idx)) is None:
                return _Fitted(best_k, g, s, f_idx, model, lengths)
            trans = more

    # Cross-validation: each fold's blocks predicted by the fit on the other folds.
    predicted = _cross_validated(fold, lambda blocks: fit_on(blocks).model)
    default = diffusion(1.0) + (transmissions.get((0, 0, 0)) if transmissions is not None else 0.0)
    final = fit_on(every)
    result = FitResult(
        material=name,
        index=material.index,
        technique=technique,
        params={},
        train_before=_rel_rmse(default - y, target),
        train_after=_rel_rmse(final.model - y, target),
        heldout_before=_rel_rmse(default - y, target),
        heldout_after=_rel_rmse(predicted - y, target),
        blocks=count,
        heldout_blocks=count,
        folds=folds,
        notes=notes,
        heldout_none=_rel_rmse(held - y, target),
    )
    params = {"gain": tuple(float(v) for v in final.g), "d_scale": float(final.k)}
    if final.lengths is not None:
        params["transmission_scale"] = tuple(float(v) for v in final.s)
        params["transmission_d_su"] = final.lengths.values(final.f_idx)
    _bounds(params, result)
    if final.k in (GRID[0], GRID[-1]):
        result.at_bounds.append("d_scale")
    if final.lengths is not None and final.lengths.at_bounds(final.f_idx):
        result.at_bounds.append("transmission_d_su")
    return _accept(result, params, samples, pixels, start, heldout_check)


@dataclass
class _Fitted:
    """One search's result: d's scale, the gains, the transmission scales and chosen lengths
    (``f_idx`` into ``lengths``' slots; ``lengths`` None without light from behind), and the
    model's block means on every block of the material."""

    k: float
    g: np.ndarray
    s: np.ndarray
    f_idx: tuple
    model: np.ndarray
    lengths: _Lengths | None


class _Transmissions:
    """The combined technique's light from behind (block means) with each channel's length
    d_tr x 2^(q/2), computed once per (q_R, q_G, q_B) whatever search asks for it."""

    def __init__(self, back, d_tr0, keep, box):
        self.back, self.d_tr0, self.keep, self.box = back, np.asarray(d_tr0, np.float64), keep, box
        self._cache: dict[tuple, np.ndarray] = {}

    def get(self, q: tuple) -> np.ndarray:
        if q not in self._cache:
            light = self.back.transmitted(tuple(self.d_tr0 * 2.0 ** (np.asarray(q) / 2.0)))
            self._cache[q] = _blocks(light, self.keep, self.box)
        return self._cache[q]


class _Lengths:
    """The combined technique's light from behind at the lengths the fit tries (block means),
    coarse to fine and per channel: each channel's length is d_tr x 2^(q/2) with q from -4 to 4
    (``GRID``), and one transmission (a "slot") carries a q per channel, since the channels do not
    mix. First q = -2, 0 and 2 for all; then, for a channel whose best q is at an end of what it
    has tried, two steps further (up to twice); then the best's neighbours one step either side.
    The fit's objective separates per channel once k is chosen, so where it has one minimum over
    the grid per channel this finds the grid's lengths with 5-7 transmissions instead of 9."""

    def __init__(self, transmissions: _Transmissions):
        self.transmissions = transmissions
        self.d_tr0 = transmissions.d_tr0
        self.slots: list[tuple[int, int, int]] = []
        self.blocks: list[np.ndarray] = []
        self.phase = "expand"
        self.expanded = 0
        lo, hi = (round(2 * math.log2(v)) for v in (GRID[0], GRID[-1]))
        self.lo, self.hi = lo, hi

    def _add(self, q) -> bool:
        q = tuple(int(min(max(v, self.lo), self.hi)) for v in q)
        if q in self.slots:
            return False
        self.slots.append(q)
        self.blocks.append(self.transmissions.get(q))
        return True

    def start(self) -> np.ndarray:
        for q in (-2, 0, 2):
            self._add((q, q, q))
        return np.stack(self.blocks)

    def exponents(self) -> np.ndarray:
        return np.asarray(self.slots, np.float64) / 2.0

    def best(self, f_idx) -> list[int]:
        return [self.slots[f_idx[c]][c] for c in range(3)]

    def next(self, f_idx) -> np.ndarray | None:
        """The slots with the next ones added after the solve chose ``f_idx``, or None when done."""
        q = self.best(f_idx)
        added = False
        if self.phase == "expand":
            step = []
            for c in range(3):
                tried = sorted({slot[c] for slot in self.slots})
                end = -2 if q[c] == tried[0] else 2 if q[c] == tried[-1] else 0
                step.append(end if self.lo <= q[c] + end <= self.hi else 0)
            if any(step) and self.expanded < 2:
                self.expanded += 1
                added = self._add([q[c] + step[c] for c in range(3)])
            if not added:
                self.phase = "refine"
        if not added and self.phase == "refine":
            self.phase = "done"
            added = self._add([v - 1 for v in q]) | self._add([v + 1 for v in q])
        return np.stack(self.blocks) if added else None

    def values(self, f_idx) -> tuple:
        q = self.best(f_idx)
        return tuple(float(self.d_tr0[c] * 2.0 ** (q[c] / 2.0)) for c in range(3))

    def at_bounds(self, f_idx) -> bool:
        return any(v in (self.lo, self.hi) for v in self.best(f_idx))


def _search(evaluate, evaluated: dict) -> float:
    """The k of lowest objective, coarse to fine: 1/2, 1 and 2, then one octave further (1/4 or
    4) while the best is at an end of what was tried, then the best's neighbours half an octave
    either side (the rest of ``GRID``), then a quarter octave. Where the objective has one
    minimum over ``GRID`` (its ridge on log2 k pulls towards 1) this finds the same k as trying
    all of ``GRID`` and refining the best, with 7-8 technique runs instead of 11."""

    lo, hi = round(4 * math.log2(GRID[0])), round(4 * math.log2(GRID[-1]))  # in quarter octaves

    def run(q: int) -> None:
        if lo <= q <= hi:
            evaluate(2.0 ** (q / 4.0))

    def best() -> int:
        return round(4 * math.log2(min(evaluated, key=lambda k: evaluated[k][0])))

    for q in (-4, 0, 4):
        run(q)
    while True:
        q = best()
        tried = sorted(round(4 * math.log2(k)) for k in evaluated)
        further = q - 4 if q == tried[0] else q + 4 if q == tried[-1] else None
        if further is None or not lo <= further <= hi:
            break
        run(further)
        if best() == q:
            break
    for step in (2, 1):
        q = best()
        run(q - step)
        run(q + step)
    return 2.0 ** (best() / 4.0)


class _Diffusion:
    """S(k): the block means of the technique's light on the material with d times k (the
    diffusion alone for the combined technique), as ``core.pipeline.apply`` gives it with the fit.

    The technique's function runs once per k with ``energy="lambert"``: the light it moves, no
    more. Its energy stage (``core/optics/energy.py``) reads the material's mean free path and the
    passes, not d, and is affine per pixel and channel in that light (out -> G out + B: the
    entry's and the convex surface's gain times what a finite object keeps, plus what comes
    through it), so G and B come from two runs of it on a frame of zeros and one of ones, once,
    and are checked against the full stage on the k = 1 light; a stage that is not affine there
    ("view": a gain renormalized to the material's total) runs on each k's light instead.
    The same result as running the whole technique for every k (``core.pipeline.apply`` with the fit's d),
    for a fraction of its cost."""

    def __init__(self, passes, scene: SceneDescription, spec, keep: np.ndarray, box: int):
        # Planned as with a fit (a gain of 1): a fitted material is computed whatever its kernel's
        # size, every channel (core.pipeline.plan), and the model must be what apply gives it then.
        (material,) = scene.materials
        fitted = dataclasses.replace(material, fit={spec.name: {"gain": (1.0, 1.0, 1.0)}})
        p = plan(passes, dataclasses.replace(scene, materials=(fitted,)), spec)
        (mp,) = p.applied
        inputs, original, ok = core_apply.technique_inputs(spec, passes, scene, p.albedo_mode)
        mask = (index_map(passes) == mp.material.index) & ok & core_apply.finite(passes["Combined"][..., :3])
        kwargs = {**inputs, **mp.params, "mask": mask, "energy": "lambert"}
        if "gain" not in spec.keywords:
            kwargs.pop("gain", None)
        if spec.adds_light:
            kwargs["transmission_scale"] = 0.0
        self.d0 = np.asarray(mp.params["d_su"], np.float64)
        if "plan_d_su" in spec.keywords:
            # One plan of Burley's adaptive counts for every k, the material's own d's: the one
            # apply gives the fitted material (core.pipeline.mapping.technique_params). A plan
            # read from each k's d would change the counts in steps as k moves, and the error
            # with them.
            kwargs["plan_d_su"] = mp.params["d_su"]
        self.spec, self.kwargs, self.keep, self.box = spec, kwargs, keep, box
        own = {k: v for k, v in mp.params.items() if k in spec.keywords}
        bound = inspect.signature(spec.function).bind_partial(**own)
        bound.apply_defaults()
        #: The technique function's keyword arguments at k = 1, defaults included.
        self.arguments = {**bound.arguments, **inputs, "mask": mask}
        self.energy = energy_inputs(self.arguments)
        if spec.adds_light:  # the combined technique's diffusion leaves the lamps behind to its transmission
            self.energy["lamps_behind"] = False
        zeros = np.zeros(original.shape, np.float32)
        self.offset = apply_energy(zeros.copy(), **self.energy)
        self.factor = apply_energy(zeros + np.float32(1.0), **self.energy) - self.offset
        self.affine = True
        light = self.scatter(1.0)
        full = apply_energy(light.copy(), **self.energy)
        affine = self.factor * light + self.offset
        scale = float(np.max(np.abs(full[mask]), initial=0.0))
        # A few float32 roundings apart at most (the same products in another order).
        self.affine = bool(np.all(np.abs(full - affine)[mask] <= _AFFINE_TOL * max(scale, 1e-30)))
        self._first = _blocks(full, keep, box)
        self._cache: dict[float, np.ndarray] = {}

    def scatter(self, k: float) -> np.ndarray:
        kwargs = {**self.kwargs, "d_su": tuple(self.d0 * k)}
        with np.errstate(over="ignore", invalid="ignore"):
            return np.asarray(call_technique(self.spec, **kwargs), np.float32)

    def __call__(self, k: float) -> np.ndarray:
        if k == 1.0:
            return self._first
        if k in self._cache:
            return self._cache[k]
        self._cache[k] = self._compute(k)
        return self._cache[k]

    def _compute(self, k: float) -> np.ndarray:
        light = self.scatter(k)
        if self.affine:
            return _blocks(self.factor * light + self.offset, self.keep, self.box)
        return _blocks(apply_energy(light, **self.energy), self.keep, self.box)


def _bounds(params: dict, result: FitResult) -> None:
    for key in ("gain", "transmission_scale"):
        if key not in params:
            continue
        lo, hi = _fit_range(key)
        values = params[key] if isinstance(params[key], tuple) else (params[key],)
        if any(v <= lo + 1e-9 or v >= hi - 1e-9 for v in values):
            result.at_bounds.append(key)


def _accept(result: FitResult, params: dict, samples, pixels: int, start: float, check: bool = True) -> FitResult:
    if not (math.isfinite(result.heldout_after) and math.isfinite(result.heldout_before)):
        raise FitError(
            f"material {result.material!r} {result.technique}: the fit did not converge (no finite error on the"
            " held-out pixels); left unchanged"
        )
    if result.heldout_after >= result.heldout_before:
        if check:
            raise HeldOutError(
                f"material {result.material!r} {result.technique}: the fit does not hold on the held-out pixels"
                f" (error {result.heldout_before:.4g} before, {result.heldout_after:.4g} after"
                f"{'' if samples is None else f', {samples} samples'}): it would fit the noise; left unchanged"
                " (render the fit with more samples)",
                result.material,
                result.technique,
            )
        result.notes.append("kept although it does not hold on the held-out blocks (held-out check off)")
    result.seconds = time.perf_counter() - start
    if check and math.isfinite(result.heldout_none) and result.heldout_after >= result.heldout_none:
        # Worse than no SSS on the held-out blocks, fit and all: the technique leaves the material
        # as it is (core/pipeline/plan.py says so), rather than making it worse.
        result.notes.append(
            f"worse than no SSS on the held-out blocks even fitted (error {result.heldout_after:.4g} against"
            f" {result.heldout_none:.4g} with no SSS): switched off on this material"
        )
        params = {OFF: 1.0}
    params[INFO] = {
        "samples": samples,
        "heldout_before": result.heldout_before,
        "heldout_after": result.heldout_after,
        "heldout_none": result.heldout_none,
        "pixels": pixels,
    }
    result.params = params
    return result


def _finish_sta(material, name, base, basis, target, fold, regularization, samples, start, pixels, check=True):
    y = target - base
    bb = float(np.sum(basis**2))
    if bb <= _ABSENT * float(np.sum(y**2)):
        raise FitError(f"material {name!r} sta: no light from behind on its pixels, nothing to fit; left unchanged")
    lo, hi = _fit_range("scale")

    def solve(blocks):
        b = float(np.sum(basis[blocks] ** 2))
        return min(
            max((float(np.sum(basis[blocks] * y[blocks])) + regularization * b) / (b * (1.0 + regularization)), lo), hi
        )

    predicted = _cross_validated(fold, lambda blocks: solve(blocks) * basis)
    s = solve(np.ones(len(fold), bool))
    result = FitResult(
        material=name,
        index=material.index,
        technique="sta",
        params={},
        train_before=_rel_rmse(basis - y, target),
        train_after=_rel_rmse(s * basis - y, target),
        heldout_before=_rel_rmse(basis - y, target),
        heldout_after=_rel_rmse(predicted - y, target),
        blocks=len(fold),
        heldout_blocks=len(fold),
        folds=int(fold.max()) + 1,
        heldout_none=_rel_rmse(y, target),
    )
    if s in (lo, hi):
        result.at_bounds.append("scale")
    return _accept(result, {"scale": s}, samples, pixels, start, check)


class _Solver:
    """Per k: the gains g_c and transmission scales s_c minimizing, over the training blocks and
    for each channel c, |y_c - g_c S_c - s_c T_c(f_c)|^2 + lam |S_c|^2 (g_c - 1)^2
    + lam |T_c|^2 (s_c - 1)^2 + lam_k (log2 f_c)^2 / 3, plus lam_k (log2 k)^2, for every length
    tried (``trans`` (F, N, 3), each slot's log2 f per channel in ``exponents`` (F, 3),
    ``_Lengths``; 2 x 2 normal equations from dot products), bounded."""

    def __init__(self, y, train, trans, regularization, exponents=None):
        self.y = y
        self.train = train
        self.trans = trans
        #: log2 of each slot's factor on the length, per channel (F, 3).
        self.log_f = exponents
        self.lam = float(regularization)
        self.yy = np.sum(y[train] ** 2, axis=0)
        # A factor 2 on d costs as much as a residual of 5 % of the target's energy, times lam.
        self.lam_k = 0.05 * self.lam * float(self.yy.sum())
        if trans is not None:
            t = trans[:, train]  # (F, N, 3)
            self.tt = np.sum(t * t, axis=1)  # (F, 3)
            self.ty = np.sum(t * y[train][None], axis=1)  # (F, 3)

    def solve(self, s_blocks: np.ndarray, k: float):
        y, tr, lam = self.y, self.train, self.lam
        st = s_blocks[tr]
        ss = np.sum(st * st, axis=0)  # (3,)
        sy = np.sum(st * y[tr], axis=0)
        glo, ghi = _fit_range("gain")
        penalty_k = self.lam_k * math.log2(k) ** 2
        if self.trans is None:
            g = np.where(ss > 0, (sy + lam * ss) / np.maximum(ss * (1.0 + lam), 1e-300), 1.0)
            g = np.clip(g, glo, ghi)
            sse = self.yy - 2 * g * sy + g * g * ss
            obj = float(np.sum(sse + lam * ss * (g - 1) ** 2)) + penalty_k
            return obj, g, np.ones(3), (GRID.index(1.0),) * 3, s_blocks * g
        # Combined: per channel c and factor f, the 2 x 2 normal equations of (g_c, s_c).
        t = self.trans[:, tr]  # (F, N, 3)
        st_f = np.sum(t * st[None], axis=1)  # (F, 3)
        tt, ty = self.tt, self.ty
        a11 = ss[None] * (1.0 + lam)
        a22 = tt * (1.0 + lam)
        det = a11 * a22 - st_f * st_f
        b1 = sy[None] + lam * ss[None]
        b2 = ty + lam * tt
        ok = np.abs(det) > 1e-12 * np.maximum(a11 * a22, 1e-300)
        safe = np.where(ok, det, 1.0)
        g = np.where(ok, (b1 * a22 - b2 * st_f) / safe, np.where(ss[None] > 0, b1 / np.maximum(a11, 1e-300), 1.0))
        s = np.where(ok, (a11 * b2 - st_f * b1) / safe, 1.0)
        slo, shi = _fit_range("transmission_scale")
        g = np.clip(g, glo, ghi)
        s = np.clip(s, slo, shi)
        sse = self.yy[None] - 2 * g * sy[None] - 2 * s * ty + g * g * ss[None] + 2 * g * s * st_f + s * s * tt
        obj_fc = sse + lam * ss[None] * (g - 1) ** 2 + lam * tt * (s - 1) ** 2 + self.lam_k * self.log_f**2 / 3.0
        f_idx = tuple(int(v) for v in np.argmin(obj_fc, axis=0))
        cols = [0, 1, 2]
        g_best, s_best = g[list(f_idx), cols], s[list(f_idx), cols]
        trans_best = self.trans[list(f_idx), :, cols].T  # (N, 3)
        model = s_blocks * g_best + s_best * trans_best
        return float(obj_fc[list(f_idx), cols].sum()) + penalty_k, g_best, s_best, f_idx, model


def fit_scene(
    passes,
    scene: SceneDescription,
    reference,
    *,
    techniques=("burley",),
    log=None,
    only=None,
    refused: list | None = None,
    **options,
) -> tuple[list[FitResult], list[str]]:
    """Fit every scattering material on screen for each of ``techniques``.

    Returns (results, problems): one ``FitResult`` per fitted (material, technique), and one line
    per material and technique that could not be fitted (it stays as it was). Raises FitError
    when no material of the scene scatters light. ``options`` go to ``fit_material``. ``only``: a
    set of (material name, technique) to fit, the others skipped. ``refused``: a list that gets
    (material name, technique, its problem line) for each fit its held-out check refused
    (``HeldOutError``).
    """
    scene = read_scene(passes, scene)  # inputs linked to textures: their medians on screen
    scattering = [m for m in scene.materials if m.scatters]
    if not scattering:
        raise FitError("no material in the scene scatters light (Subsurface Weight > 0): nothing to fit")
    results, problems = [], []
    for material in scattering:
        for technique in techniques:
            if only is not None and (material.name or str(material.index), technique) not in only:
                continue
            try:
                r = fit_material(passes, scene, reference, material, technique, **options)
            except FitError as exc:
                if refused is not None and isinstance(exc, HeldOutError):
                    refused.append((exc.material, exc.technique, str(exc)))
                problems.append(str(exc))
                if log:
                    log(f"  {exc}")
                continue
            results.append(r)
            if log:
                log(f"  {r.summary()}")
    return results, problems


def with_fits(scene: SceneDescription, results: list[FitResult]) -> SceneDescription:
    """``scene`` with each fitted material's ``fit`` updated (other techniques' fits kept)."""
    by_index: dict[int, dict] = {}
    for r in results:
        by_index.setdefault(r.index, {})[r.technique] = r.params
    materials = []
    for m in scene.materials:
        if m.index in by_index:
            m = dataclasses.replace(m, fit={**m.fit, **by_index[m.index]})
        materials.append(m)
    return dataclasses.replace(scene, materials=tuple(materials))
