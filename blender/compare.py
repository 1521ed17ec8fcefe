"""Compare each technique with Cycles' random-walk SSS on the user's own scene.

``compare(scene, out_dir)`` renders

- the reference: the scene as it is (its own subsurface method, normally Random Walk), fixed
  seed, adaptive sampling off (docs/references.md §8), cached by a fingerprint of the scene
  and the settings so that a second run of an unchanged scene does not render it again;
- the noise floor: the same reference with another seed, compared with the same metric;
- peers: Cycles at lower sample counts, and Cycles' own Christensen-Burley method;
- the passes the techniques need (``render_passes``: SSS rendered as plain diffuse), and the same
  passes at ``bias_samples`` to split each technique's error into bias and pass noise
  (``core.study.metrics.split_error``);

then applies every technique at several quality settings with ``core.pipeline.apply``, and writes the
report (``core.study.report``): metrics.json, report.md, report.html, grid.png, pareto.svg.

The Cycles images come from ``blender.reference_cache``. The scene is left as it was
(``SceneState``), also when a step fails. ``bpy.ops.sss_lab.compare`` (``operators/comparison.py``)
runs it from the panel.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import bpy
import numpy as np

from ..core.base import files
from ..core.base.errors import InputError, SSSLabError
from ..core.base.progress import printable, saved_line
from ..core.pipeline import apply as core_apply
from ..core.pipeline import plan, sequence
from ..core.scene import exr
from ..core.scene.inputs import read_scene
from ..core.scene.scene import SUBSURFACE_METHODS, SceneDescription
from ..core.study import fidelity, metrics, report
from ..core.study import reference as core_reference
from ..core.study.sweep import calibrate
from ..core.techniques.registry import TECHNIQUES, check_technique, get_spec
from ..core.techniques.spec import CALIBRATE_MAPPING, Technique
from . import compat
from .describe import sss_materials
from .jobs import Job, Steps, run
from .reference_cache import cached_reference, scene_fingerprint


@dataclass
class CompareSettings:
    """What ``compare`` renders and measures. Resolution None keeps the scene's."""

    resolution: tuple[int, int] | None = None
    reference_samples: int = 256
    pass_samples: int = 64
    seed: int = 0
    peer_samples: tuple[int, ...] = (16, 64)
    #: Cycles random walk at these samples denoised by OpenImageDenoise, what a user wanting a quick
    #: faithful picture renders; each twice (two seeds) so that the denoiser's bias is shown apart
    #: from the noise it leaves. () leaves them out.
    denoise_samples: tuple[int, ...] = (4, 16)
    cycles_burley: bool = True
    box: int = 2
    techniques: tuple[str, ...] = tuple(TECHNIQUES)
    #: Quality ladder per technique (keyword arguments per run, cheapest first); default: each
    #: technique's own (``Technique.qualities``).
    qualities: dict = field(default_factory=lambda: {name: t.qualities for name, t in TECHNIQUES.items()})
    cache_dir: str | None = None
    #: Other subsurface methods to calibrate the mapping for: the reference is rendered again with
    #: the scene's subsurface materials switched to each (cached like the others).
    calibrate_methods: tuple[str, ...] = ()
    #: A reference merged from seed parts (``sss_lab merge-reference``, e.g. rendered on a farm)
    #: instead of rendering one: its samples replace ``reference_samples``, its halves give the
    #: noise floor, and the Christensen-Burley peer (as costly as the reference) is left out.
    reference_file: str | None = None

    #: Samples of the second set of passes that splits each technique's error into bias and pass
    #: noise: more than ``pass_samples``; None = 4 x ``pass_samples``; 0 leaves the split out.
    bias_samples: int | None = None
    #: EEVEE as a peer (``blender/eevee.py``): rendered with scattering on and off, scored on its
    #: image and on its SSS effect. Off: not rendered.
    eevee: bool = True
    #: EEVEE's render samples; None keeps the scene's own (its render setting).
    eevee_samples: int | None = None

    @property
    def bias_pass_samples(self) -> int:
        """The samples of the bias passes (0: none)."""
        return 4 * self.pass_samples if self.bias_samples is None else self.bias_samples

    def validate(self) -> None:
        for name in ("reference_samples", "pass_samples", "box"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ValueError(f"{name}: expected an integer >= 1, got {v!r}")
        b = self.bias_samples
        if b is not None and (not isinstance(b, int) or isinstance(b, bool) or (b and b <= self.pass_samples) or b < 0):
            raise ValueError(
                f"bias_samples: expected 0 (off) or an integer > pass_samples ({self.pass_samples}),"
                f" got {self.bias_samples!r}"
            )
        e = self.eevee_samples
        if e is not None and (not isinstance(e, int) or isinstance(e, bool) or e < 1):
            raise ValueError(f"eevee_samples: expected an integer >= 1 (or None: the scene's own), got {e!r}")
        for name in ("peer_samples", "denoise_samples"):
            values = getattr(self, name)
            if any(not isinstance(s, int) or isinstance(s, bool) or s < 1 for s in values):
                raise ValueError(f"{name}: expected integers >= 1, got {values!r}")
        if self.resolution is not None:
            w, h = self.resolution
            if not (isinstance(w, int) and isinstance(h, int) and w >= 1 and h >= 1):
                raise ValueError(f"resolution: expected two integers >= 1 (W, H), got {self.resolution!r}")
            if min(w, h) < self.box:
                raise ValueError(
                    f"resolution: {w}x{h} is smaller than the {self.box}x{self.box} box the metrics average over;"
                    f" expected at least {self.box} pixels a side (or a smaller --box)"
                )
        for t in self.techniques:
            check_technique(t)
        for m in self.calibrate_methods:
            if m not in SUBSURFACE_METHODS:
                raise ValueError(f"calibrate_methods: unknown subsurface method {m!r}; expected: {SUBSURFACE_METHODS}")
            if m not in compat.subsurface_methods():
                raise ValueError(
                    f"calibrate_methods: Blender {bpy.app.version_string} has no subsurface method {m!r};"
                    f" expected some of: {compat.subsurface_methods()}"
                )


def _number(value) -> str:
    """A metric for the log; None (no pixel of a scattering material to measure) as 'n/a'."""
    return "n/a" if value is None else f"{value:.4f}"


def compare(scene, out_dir: str, settings: CompareSettings | None = None, *, log=print) -> dict:
    """Run the whole comparison and write the report into ``out_dir``; returns the report data.
    (``compare_job`` to its end.)"""
    return run(compare_job(scene, out_dir, settings, log=log))


def compare_job(scene, out_dir: str, settings: CompareSettings | None = None, *, log=print) -> Job:
    """The comparison as a job generator (``blender/jobs.py``): one step per Cycles render
    (each reference, the passes, each peer), per technique run, and the report. Cancelled
    between steps, the scene is restored and the references rendered so far stay in the cache,
    so that the next run starts where this one stopped.

    Raises ValueError for a scene without a camera or without subsurface materials (nothing to
    compare). A technique that cannot run on this scene (e.g. a subsurface method the mapping
    does not know, or STA without a thickness map) or that fails (``TECHNIQUE_ERRORS``) is noted
    in the report, which then says it is incomplete; the other techniques are measured.
    """
    settings, materials, notes = _checked(scene, settings or CompareSettings(), log)
    cache_dir = settings.cache_dir or os.path.join(out_dir, "cache")
    blocker = files.not_a_folder(cache_dir)
    if blocker is not None:  # before anything renders: a render whose result cannot be kept is lost
        raise ValueError(
            f"cache_dir {printable(cache_dir)!r}: {printable(blocker)!r} is not a folder; expected a folder for the"
            " reference cache"
        )
    steps = Steps(_step_count(settings, {m.method for m in materials}))
    spp = settings.reference_samples
    first = f"Cycles reference, {spp} samples, seed {settings.seed}"
    yield steps.next("merged reference" if settings.reference_file else first)  # checked; nothing changed yet
    timings: dict[str, float] = {}
    res = settings.resolution

    fingerprint = scene_fingerprint(scene)
    merged = None
    if settings.reference_file:  # read and checked before anything is written
        merged, ref_seconds = _merged_reference(settings.reference_file, fingerprint, res, scene.frame_current, log)
        settings = dataclasses.replace(settings, reference_samples=merged.samples, cycles_burley=False)
    os.makedirs(out_dir, exist_ok=True)
    # Every Cycles image of this comparison: same scene, folder and size; samples, seed and method vary.
    reference = functools.partial(cached_reference, scene, cache_dir, resolution=res, log=log, fingerprint=fingerprint)
    if merged is not None:
        ref, second = merged.image, None
    else:
        ref, ref_seconds, _ = reference(samples=settings.reference_samples, seed=settings.seed, method=None)
        yield steps.next(f"Cycles reference, {spp} samples, seed {settings.seed + 1} (noise floor)")
        second, _, _ = reference(samples=settings.reference_samples, seed=settings.seed + 1, method=None)
    passes, desc, high = yield from _render_passes(scene, out_dir, settings, steps, timings, log)
    mask = _scattering_mask(passes, desc, ref)
    rows = _Rows(ref, mask, settings, log, materials=material_masks(passes, desc))
    rows.add("no SSS", "baseline", passes["Combined"], timings["passes"], image_high=high and high[0]["Combined"])
    for technique in settings.techniques:
        for quality in settings.qualities.get(technique, ({},)):
            yield steps.next(TECHNIQUES[technique].quality_label(quality))
            run = technique_run(passes, desc, technique, quality, high, notes, log)
            if run is not None:
                total = timings["passes"] + run.apply_s
                extra = {
                    "technique": technique,
                    "quality": quality,
                    "samples_per_pixel": TECHNIQUES[technique].samples_per_pixel(quality, len(desc.lights)),
                }
                rows.add(run.label, "technique", run.image, total, run.apply_s, extra, image_high=run.image_high)
                rows.entries[-1]["time_s"]["sss_effect_spread"] = list(run.apply_spread)
                rows.entries[-1]["time_s"]["sss_effect_runs"] = run.runs
    rw_at_pass_samples = yield from _peers(settings, reference, rows, timings, steps)
    eevee = None
    if settings.eevee:
        eevee = yield from _eevee(scene, settings, cache_dir, fingerprint, passes, rows, steps, log)

    rows.images["Cycles reference"] = ref
    if merged is not None:
        noise = core_reference.noise_floor(merged, mask, box=settings.box)
    else:
        assert second is not None  # rendered above when there is no merged reference
        noise = metrics.compare_images(second, ref, mask, box=settings.box)
    calibration = yield from _calibration(settings, passes, desc, ref, mask, reference, steps)
    yield steps.next("report")
    data = {
        "scene": {
            "name": _scene_label(scene),
            "file": bpy.data.filepath,
            # As the techniques read them: inputs linked to textures at their medians, with the notes.
            "materials": [asdict(m) for m in read_scene(passes, desc).materials],
            "fingerprint": fingerprint,
            # Lights the techniques read (a technique that adds light evaluates each per pixel).
            "lights": len(desc.lights),
        },
        "settings": _settings_data(settings, materials, ref, ref_seconds, merged),
        "noise_floor": noise,
        "timings": timings,
        "costs": _costs(settings, timings, rw_at_pass_samples, rows.entries),
        "entries": rows.entries,
        "fidelity": _fidelity(desc, settings.techniques, notes),
        "calibration": calibration,
        "eevee": eevee,
        "notes": notes,
        "complete": not notes,
    }
    return _write(out_dir, data, rows, mask, log)


#: What a technique's run (or its row of the fidelity table) may raise that leaves the comparison
#: to measure the other techniques, with a note in the report: an error SSS Lab raises on purpose,
#: a missing pass, a bad value, a technique function that does not take its inputs or overflows.
TECHNIQUE_ERRORS = (SSSLabError, TypeError, ValueError, KeyError, ArithmeticError)


def _error_text(exc: BaseException) -> str:
    """The error for a note: its message, with its type for one SSS Lab does not raise on purpose."""
    if isinstance(exc, (SSSLabError, ValueError, KeyError)):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


def _checked(scene, settings: CompareSettings, log) -> tuple[CompareSettings, list, list[str]]:
    """(the settings without the techniques that cannot run here, the scene's subsurface materials,
    the notes on what is left out). Changes nothing but the thickness AOV's set-up."""
    settings.validate()
    if scene.camera is None:
        raise ValueError(f"scene {scene.name!r} has no active camera; set one in Scene Properties > Camera")
    materials = sss_materials(scene)
    if not materials:
        raise ValueError(
            f"scene {scene.name!r} has no material with subsurface scattering (Subsurface Weight > 0):"
            " nothing to compare"
        )
    notes: list[str] = []
    techniques = tuple(settings.techniques)
    needs_thickness = tuple(t for t in techniques if TECHNIQUES[t].reads_thickness)
    if needs_thickness:
        from .thickness import thickness_aov_name, thickness_setup

        try:
            thickness_setup(scene, materials, thickness_aov_name(scene))
        except ValueError as exc:
            # Checked before anything renders: the other techniques still get their report.
            techniques = tuple(t for t in techniques if t not in needs_thickness)
            for t in needs_thickness:  # one note per technique, each by its label
                notes.append(f"{TECHNIQUES[t].label} not run: {exc}")
                log(notes[-1])
            if not techniques:
                raise
        settings = dataclasses.replace(settings, techniques=techniques)
    return settings, materials, notes


def _render_passes(scene, out_dir: str, settings: CompareSettings, steps: Steps, timings: dict, log):
    """The passes the techniques read, and those at the bias samples (or None). A generator: one
    step per render; returns (passes, scene description, (bias passes, their description) | None)."""
    from .render_passes import render_passes

    def render(folder: str, samples: int, seed: int, timing: str) -> tuple[exr.Passes, SceneDescription]:
        start = time.perf_counter()
        written = render_passes(
            scene,
            os.path.join(out_dir, folder),
            techniques=settings.techniques,
            samples=samples,
            resolution=settings.resolution,
            seed=seed,
            overwrite=True,
            log=log,
        )
        timings[timing] = time.perf_counter() - start
        path = next(p for p in written if p.endswith(".exr"))
        return exr.read_passes(path), sequence.load_scene(path)

    yield steps.next(f"passes, {settings.pass_samples} samples")
    log(f"Passes: {settings.pass_samples} samples, subsurface as plain diffuse")
    passes, desc = render("passes", settings.pass_samples, settings.seed, "passes")
    high = None
    if settings.bias_pass_samples:
        yield steps.next(f"passes, {settings.bias_pass_samples} samples (bias and pass noise)")
        log(f"Passes: {settings.bias_pass_samples} samples, to split each technique's error into bias and pass noise")
        high = render("passes_bias", settings.bias_pass_samples, settings.seed + 4, "passes_bias")
    return passes, desc, high


def material_masks(passes, desc: SceneDescription) -> dict[str, np.ndarray]:
    """Each scattering material's pixels (Material Index, ``plan.index_map``), by name: every
    score is also measured on each of them."""
    index = plan.index_map(passes)
    return {m.name: index == m.index for m in desc.materials if m.scatters}


def _scattering_mask(passes, desc: SceneDescription, ref: np.ndarray) -> np.ndarray:
    """The pixels of the scattering materials, where every image is measured."""
    mask = np.isin(plan.index_map(passes), [m.index for m in desc.materials if m.scatters])
    if ref.shape[:2] != mask.shape:
        raise ValueError(f"reference {ref.shape[:2]} and passes {mask.shape} differ in size")
    if not mask.any():
        names = ", ".join(repr(m.name) for m in desc.materials if m.scatters)
        raise InputError(
            f"no pixel of a subsurface material ({printable(names)}) is on screen in the camera's"
            f" {mask.shape[1]}x{mask.shape[0]} view: nothing to compare; point the camera at it or render larger"
        )
    return mask


@dataclass
class _Rows:
    """The report's measured rows (``entries``) and their images, against the reference over the
    scattering pixels."""

    ref: np.ndarray
    mask: np.ndarray
    settings: CompareSettings
    log: Callable[[str], object]
    entries: list[dict] = field(default_factory=list)
    images: dict[str, np.ndarray] = field(default_factory=dict)
    #: Each scattering material's pixels (``material_masks``): the scores per material.
    materials: dict[str, np.ndarray] = field(default_factory=dict)

    def add(self, name, kind, image, total, apply_s=None, extra=None, image_high=None) -> None:
        settings = self.settings
        m = metrics.compare_images(image, self.ref, self.mask, box=settings.box)
        if image_high is not None and m["rel_rmse"] is not None:
            m_high = metrics.compare_images(image_high, self.ref, self.mask, box=settings.box)["rel_rmse"]
            m["bias"], m["pass_noise"] = metrics.split_error(
                m["rel_rmse"], m_high, settings.pass_samples, settings.bias_pass_samples
            )
        # A technique's SSS effect costs its apply; end to end it also needs the passes.
        entry = {
            "name": name,
            "kind": kind,
            "metrics": m,
            "time_s": {"total": total, "apply": apply_s, "sss_effect": apply_s},
        }
        if len(self.materials) > 1:
            entry["by_material"] = {
                name: metrics.compare_images(image, self.ref, on, box=settings.box)
                for name, on in self.materials.items()
            }
        entry.update(extra or {})
        self.entries.append(entry)
        self.images[name] = image
        self.log(f"  {name}: rel. RMSE {_number(m['rel_rmse'])}, SSIM {_number(m['ssim'])}, {total:.2f} s")


@dataclass
class TechniqueRun:
    """One quality of a technique run on the passes: its image (and on the bias passes), seconds."""

    label: str
    image: np.ndarray
    image_high: np.ndarray | None
    #: The median of the timed runs, and their fastest and slowest (the clock's spread).
    apply_s: float
    apply_spread: tuple[float, float] = (0.0, 0.0)
    runs: int = 1


#: Timed runs of each technique quality (their median is its cost: one run sits inside the
#: machine's noise at a few milliseconds), fewer when they add up past ``TIMING_BUDGET_S``.
TIMING_RUNS = 5
TIMING_BUDGET_S = 2.0


def technique_run(
    passes, desc: SceneDescription, technique: str | Technique, quality: dict, high, notes: list[str], log
) -> TechniqueRun | None:
    """``technique`` at ``quality`` on ``passes`` (and on ``high``, the bias passes and their
    description, if given); None, with a note, when it fails (``TECHNIQUE_ERRORS``) or changes
    no material on screen."""
    spec = get_spec(technique)
    label = spec.quality_label(quality)
    try:
        # Untimed first run of every quality: it compiles the kernels of the quality's own
        # code path (or loads them from Numba's cache) and builds its one-off tables (STA's
        # medium falloff: the walk's tables), seconds that are no part of what the
        # technique costs a frame. Warming only a technique's first quality let STA's
        # second quality report 0.4-19 s at 128 px where it takes milliseconds.
        core_apply.apply(passes, desc, spec, prepared=plan.plan(passes, desc, spec, **quality), **quality)
        seconds: list[float] = []
        while len(seconds) < TIMING_RUNS and sum(seconds) < TIMING_BUDGET_S:
            start = time.perf_counter()
            prepared = plan.plan(passes, desc, spec, **quality)
            layers = core_apply.apply(passes, desc, spec, prepared=prepared, **quality)
            seconds.append(time.perf_counter() - start)
        apply_s = float(np.median(seconds))
        for m in prepared.applied:
            if m.warning:  # a kernel beyond the material or the image (a units slip?): say so
                log(f"  {label}: warning: material {m.material.name or m.material.index!r}: {m.warning}")
        if not layers:
            notes.append(f"{label}: no material scattered on screen")
            return None
        name = core_apply.layer_names(spec.name)[0]
        image_high = None
        if high is not None:
            layers_high = core_apply.apply(high[0], high[1], spec, **quality)
            image_high = layers_high[name] if layers_high else high[0]["Combined"]
    except TECHNIQUE_ERRORS as exc:
        notes.append(f"{label} did not run: {_error_text(exc)}")
        log(f"  {label}: not run ({_error_text(exc)})")
        return None
    return TechniqueRun(label, layers[name], image_high, apply_s, (min(seconds), max(seconds)), len(seconds))


def _peers(settings: CompareSettings, reference, rows: _Rows, timings: dict, steps: Steps):
    """Cycles at the peer sample counts (and Christensen-Burley). A generator: one step per
    render; returns the seconds of Cycles random walk at the passes' samples (None: not rendered)."""
    # Cycles random walk at the passes' samples is always among the peers: against the passes (Cycles
    # without SSS at the same samples) it gives what the SSS effect costs Cycles.
    peers = sorted({*settings.peer_samples, settings.pass_samples})
    rw_at_pass_samples = None
    for samples in peers:
        if samples >= settings.reference_samples:
            continue
        yield steps.next(f"Cycles {samples} samples")
        img, secs, _ = reference(samples=samples, seed=settings.seed + 2, method=None)
        rows.add(f"Cycles {samples} spp", "cycles", img, secs, extra={"samples_per_pixel": samples})
        rows.entries[-1]["time_s"]["sss_effect"] = None
        if samples == settings.pass_samples:
            rw_at_pass_samples = secs
            rows.entries[-1]["time_s"]["sss_effect"] = secs - timings["passes"]
    for samples in sorted(set(settings.denoise_samples)):
        if samples >= settings.reference_samples:
            continue
        yield steps.next(f"Cycles {samples} samples, denoised (OpenImageDenoise)")
        img, secs, _ = reference(samples=samples, seed=settings.seed + 2, method=None, denoise=True)
        yield steps.next(f"Cycles {samples} samples, denoised, another seed (its bias apart from its noise)")
        other, _, _ = reference(samples=samples, seed=settings.seed + 4, method=None, denoise=True)
        rows.add(f"Cycles {samples} spp + OIDN", "cycles", img, secs, extra={"samples_per_pixel": samples})
        m = rows.entries[-1]["metrics"]
        m["bias"], m["pass_noise"] = metrics.split_seeds(img, other, rows.ref, rows.mask, box=settings.box)
        rows.entries[-1]["time_s"]["sss_effect"] = None
    if settings.cycles_burley:
        yield steps.next(f"Cycles Christensen-Burley, {settings.reference_samples} samples")
        img, secs, _ = reference(samples=settings.reference_samples, seed=settings.seed + 3, method="BURLEY")
        spp = settings.reference_samples
        rows.add(f"Cycles Christensen-Burley {spp} spp", "cycles", img, secs, extra={"samples_per_pixel": spp})
    return rw_at_pass_samples


def _eevee(scene, settings: CompareSettings, cache_dir: str, fingerprint: str, passes, rows: _Rows, steps: Steps, log):
    """EEVEE as a peer (``blender/eevee.py``): its image with scattering, and its SSS effect (with
    minus without) on Cycles' image without scattering. A generator: one step per render; returns
    what was measured, or why EEVEE could not render here (the rest of the comparison goes on)."""
    from .eevee import EeveeUnavailable, cached_eevee

    samples = settings.eevee_samples or scene.eevee.taa_render_samples
    images = {}
    try:
        for sss in (True, False):
            yield steps.next(f"EEVEE {samples} samples, scattering {'on' if sss else 'off'}")
            images[sss] = cached_eevee(
                scene,
                cache_dir,
                samples=settings.eevee_samples,
                resolution=settings.resolution,
                sss=sss,
                fingerprint=fingerprint,
                log=log,
            )
    except EeveeUnavailable as exc:
        log(f"note: {exc}; EEVEE is left out of the comparison")
        return {"samples": samples, "error": str(exc)}
    (on, on_s, _), (off, off_s, _) = images[True], images[False]
    if on.shape[:2] != rows.ref.shape[:2]:
        h, w = rows.ref.shape[:2]
        raise ValueError(f"EEVEE rendered {on.shape[1]}x{on.shape[0]}, the reference is {w}x{h}")
    info = {"samples": samples, "seconds_with_sss": on_s, "seconds_without_sss": off_s}
    rows.add(
        f"EEVEE {samples} samples",
        "eevee",
        on,
        on_s,
        extra={"eevee": dict(info, image="as rendered"), "samples_per_pixel": samples},
    )
    # Its SSS effect on Cycles' image without scattering: scored like a technique's image, its share of
    # the no-SSS error removed is the share of Cycles' SSS effect it reproduces.
    effect = np.array(passes["Combined"], dtype=np.float32)
    effect[..., :3] += on[..., :3] - off[..., :3]
    rows.add(
        f"EEVEE {samples} samples, SSS effect",
        "eevee",
        effect,
        on_s,
        max(on_s - off_s, 0.0),
        extra={
            "eevee": dict(info, image="Cycles without SSS + (EEVEE with SSS - EEVEE without)"),
            "samples_per_pixel": samples,
        },
    )
    # What its SSS costs EEVEE: the frame with it against the frame without (no apply of its own).
    rows.entries[-1]["time_s"] = {"total": on_s, "apply": None, "sss_effect": max(on_s - off_s, 0.0)}
    return info


def _settings_data(settings: CompareSettings, materials, ref: np.ndarray, ref_seconds: float, merged) -> dict:
    """The report's ``settings``: what was rendered and measured."""
    return {
        "resolution": list(ref.shape[1::-1]),
        "reference_samples": settings.reference_samples,
        "reference_seconds": ref_seconds,
        "pass_samples": settings.pass_samples,
        "bias_pass_samples": settings.bias_pass_samples,
        "seed": settings.seed,
        "box": settings.box,
        "reference_method": "scene's own subsurface method (" + ", ".join(sorted({m.method for m in materials})) + ")",
        "blender": bpy.app.version_string,
        "reference_file": settings.reference_file,
        "reference_seeds": list(merged.seeds) if merged is not None else [settings.seed],
    }


def _write(out_dir: str, data: dict, rows: _Rows, mask: np.ndarray, log) -> dict:
    """Write the report folder (``core.study.report``): the rows in the order no SSS, the techniques,
    Cycles' renders, the reference."""
    entries = rows.entries
    order = (
        ["no SSS"]
        + [e["name"] for e in entries if e["kind"] == "technique"]
        + [e["name"] for e in entries if e["kind"] == "cycles"]
        + [e["name"] for e in entries if e["kind"] == "eevee"]
        + ["Cycles reference"]
    )
    out = report.write_report(
        out_dir,
        data,
        rows.images,
        reference="Cycles reference",
        mask=mask,
        order=order,
        summary=_summary(order, entries),
    )
    for path in report.report_files(out_dir, out):  # a Saved line for every file, report.html last
        log(saved_line(path))
    return out


def _merged_reference(
    path: str, fingerprint: str, resolution, frame: int, log
) -> tuple[core_reference.MergedReference, float]:
    """The merged reference at ``path`` and its render seconds (the parts' sum), checked against
    the scene: a reference of another scene state would make every figure meaningless."""
    merged = core_reference.read_merged(path)
    meta_path = core_reference.sidecar(path)
    meta = core_reference.read_meta(meta_path) if os.path.isfile(meta_path) else {}
    if meta.get("frame") is not None and meta["frame"] != frame:
        raise InputError(
            f"{path} shows frame {meta['frame']}; the comparison is of frame {frame}: compare that frame "
            f"(--frames {meta['frame']}) or render the parts at this one"
        )
    if meta.get("fingerprint") and meta["fingerprint"] != fingerprint:
        raise InputError(
            f"{path} was rendered from another state of the scene (its fingerprint differs from this scene's): "
            "render the reference parts again from this file"
        )
    if resolution is not None and list(merged.image.shape[1::-1]) != list(resolution):
        raise InputError(
            f"{path} is {merged.image.shape[1]}x{merged.image.shape[0]}; the comparison renders "
            f"{resolution[0]}x{resolution[1]}: render the parts at that size, or compare at the reference's"
        )
    log(f"Reference: {path}, {merged.samples} samples merged from seeds {', '.join(map(str, merged.seeds))}")
    return merged, float(meta.get("seconds") or 0.0)


def _costs(settings: CompareSettings, timings: dict, rw_seconds, entries: list[dict]) -> dict:
    """The two costs of each technique against Cycles: the SSS effect alone and end to end."""
    cycles_sss = None if rw_seconds is None else rw_seconds - timings["passes"]
    return {
        "definition": (
            f"SSS effect alone: a technique's apply time, against Cycles random walk at {settings.pass_samples}"
            " samples minus Cycles without SSS at the same samples (the passes' render). End to end: the passes'"
            " render plus the apply, against the random-walk render. Wall-clock seconds on this machine; a cached"
            " Cycles image keeps the time measured when it was rendered."
        ),
        "samples": settings.pass_samples,
        "cycles_random_walk_s": rw_seconds,
        "cycles_without_sss_s": timings["passes"],
        "cycles_sss_effect_s": cycles_sss,
        "techniques": [
            {"name": e["name"], "sss_effect_s": e["time_s"]["apply"], "end_to_end_s": e["time_s"]["total"]}
            for e in entries
            if e["kind"] == "technique"
        ],
    }


def _summary(order: list[str], entries: list[dict]) -> list[str]:
    """Columns of summary.png: no SSS, each technique at its default quality (or its last), the
    reference."""
    picked = ["no SSS"]
    for technique, spec in TECHNIQUES.items():
        runs = [e for e in entries if e.get("technique") == technique]
        if runs:
            best = [e for e in runs if e.get("quality") == dict(spec.default_run)]
            picked.append((best or runs)[-1]["name"])
    return [n for n in picked if n in order] + ["Cycles reference"]


def _scene_label(scene) -> str:
    """``file.blend / Scene``, or the scene's name alone for an unsaved file."""
    path = bpy.data.filepath
    return f"{os.path.basename(path)} / {scene.name}" if path else scene.name


def _fidelity(desc: SceneDescription, techniques, notes: list) -> dict | None:
    """The fidelity table of the techniques that can be measured (``core.study.fidelity``); each that
    fails is left out with a note. None when no material scatters or no technique could be."""
    try:
        material = _main_material(desc)
    except ValueError as exc:
        notes.append(f"fidelity table not measured: {exc}")
        return None
    rows = {}
    for technique in techniques:
        spec = get_spec(technique)
        try:
            rows[spec.label] = fidelity.measure(spec, material)
        except TECHNIQUE_ERRORS as exc:
            notes.append(f"fidelity table: {spec.label} not measured: {_error_text(exc)}")
    if not rows:
        return None
    table = fidelity.fidelity_table(material, techniques=())  # the definition and the profile's own row
    table["rows"] = {**rows, **table["rows"]}
    return table


def _main_material(desc: SceneDescription):
    """The scattering material the fidelity table is measured with: the one with the widest radius."""
    return max((m for m in desc.materials if m.scatters), key=lambda m: max(m.radius))


def _calibration_methods(settings: CompareSettings, own: set) -> list[str]:
    """The subsurface methods the calibration renders a reference for (for the techniques that
    calibrate the material mapping)."""
    if not any(TECHNIQUES[t].calibration == CALIBRATE_MAPPING for t in settings.techniques):
        return []
    return [m for m in settings.calibrate_methods if m not in own]


def _step_count(settings: CompareSettings, own: set) -> int:
    """Steps of ``compare_job``: two references (or the merged one), the passes (and those for the
    bias split), each technique run, each peer, the calibration references, the report."""
    refs = 1 if settings.reference_file else 2
    passes = 1 + bool(settings.bias_pass_samples)
    runs = sum(len(settings.qualities.get(t, ({},))) for t in settings.techniques)
    peers = sum(1 for s in {*settings.peer_samples, settings.pass_samples} if s < settings.reference_samples)
    peers += 2 * sum(1 for s in set(settings.denoise_samples) if s < settings.reference_samples)  # two seeds each
    peers += bool(settings.cycles_burley and not settings.reference_file)
    peers += 2 * bool(settings.eevee)  # with and without scattering
    return refs + passes + runs + peers + len(_calibration_methods(settings, own)) + 1


def _calibration(settings: CompareSettings, passes, desc: SceneDescription, ref, mask, reference, steps: Steps):
    """The scene's own methods against its reference, then each method of
    ``settings.calibrate_methods`` against a reference rendered with it (``reference``: the
    comparison's ``cached_reference`` with the scene and size bound). A generator: one step per
    reference it renders; returns the table."""
    result = calibrate(passes, desc, ref, mask, box=settings.box, techniques=settings.techniques)
    own = {m.method for m in desc.materials if m.scatters}
    scattering = tuple(t for t in settings.techniques if TECHNIQUES[t].calibration == CALIBRATE_MAPPING)
    for method in _calibration_methods(settings, own):
        yield steps.next(f"Cycles reference with {method} for the calibration")
        method_ref, _, _ = reference(samples=settings.reference_samples, seed=settings.seed, method=method)
        as_method = dataclasses.replace(
            desc,
            materials=tuple(dataclasses.replace(m, method=method) if m.scatters else m for m in desc.materials),
        )
        base = metrics.compare_images(passes["Combined"], method_ref, mask, box=settings.box)
        result["rows"].append({"method": method, "technique": "no SSS", "mapping": "-", "rel_rmse": base["rel_rmse"]})
        result["rows"] += calibrate(passes, as_method, method_ref, mask, box=settings.box, techniques=scattering)[
            "rows"
        ]
    return result
