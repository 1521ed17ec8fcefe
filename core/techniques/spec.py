"""What a technique is, declared once: the ``Technique`` spec and its ``Param`` specs.

Each technique module declares a frozen ``Technique`` beside its function (``core/techniques/sta/technique.py``
``TECHNIQUE`` ...) and ``core/techniques/registry.py`` lists them in one registry. Every layer reads the
spec instead of branching on a technique's name: planning and compositing (``passes``,
``scatters``, ``adds_light``, ``footprint``), the material mapping (the function's keywords),
the fidelity table, the comparison (``qualities``, ``default_quality``, ``calibration``), the
render passes and the compositor set-up (``passes``), the panel's properties and rows and the
command line's ``--param`` (``params``), what ``calibrate`` fits (``fit``), whether ``auto`` may
choose it (``auto``). Adding a technique: ``docs/adding-a-technique.md``.

Defaults live in the function's signature only: a ``Param`` is declared without one and the
``Technique`` fills it in from the signature (a parameter the function does not take, or takes
without a default, is an error when the module is imported).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base.errors import InputError
from ..optics.profiles import TRUNCATION
from ..scene.passes import PASSES, THICKNESS

#: The value types a parameter may have (the panel's property and the command line's parser follow it).
PARAM_TYPES: tuple[type, ...] = (float, int, bool, str)

#: ``Technique.calibration``: sweep the material mappings of ``core/pipeline/mapping.py`` per subsurface method.
CALIBRATE_MAPPING = "mapping"


@dataclass(frozen=True)
class Param:
    """One parameter a user may set: a keyword of the technique's function.

    ``choices``: the allowed values (value, label, description), for a parameter that takes one
    of a few values; ``min``/``max``: the allowed range (inclusive, None: open); ``soft_max``:
    where the panel's slider ends (not a limit). ``default`` comes from the function's signature.
    """

    name: str
    label: str
    description: str
    type: type = float
    min: float | None = None
    max: float | None = None
    soft_max: float | None = None
    choices: tuple[tuple[Any, str, str], ...] = ()
    default: Any = None

    def __post_init__(self) -> None:
        if self.type not in PARAM_TYPES:
            raise TypeError(f"parameter {self.name!r}: type {self.type!r} is not one of {PARAM_TYPES}")

    @property
    def values(self) -> tuple[Any, ...]:
        """The allowed values when the parameter has ``choices``, else ()."""
        return tuple(value for value, _, _ in self.choices)

    def allowed(self) -> str:
        """The allowed values or range, in words (for error messages and help)."""
        if self.choices:
            return "one of " + ", ".join(str(v) for v in self.values)
        what = {float: "a number", int: "an integer", bool: "true or false", str: "text"}[self.type]
        if self.min is not None and self.max is not None:
            return f"{what} in [{self.min:g}, {self.max:g}]"
        if self.min is not None:
            return f"{what} >= {self.min:g}"
        if self.max is not None:
            return f"{what} <= {self.max:g}"
        return what

    def check(self, value: Any, where: str = "") -> Any:
        """``value`` as this parameter's type, within its range or choices; InputError naming the
        parameter, the value and what is allowed otherwise."""
        name = f"{where}{self.name}"
        try:
            if self.type is bool:
                if not isinstance(value, (bool, np.bool_, int, np.integer)) or value not in (0, 1):
                    raise ValueError
                out: Any = bool(value)
            elif self.type is int:
                if isinstance(value, (bool, np.bool_)) or float(value) != int(value):
                    raise ValueError
                out = int(value)
            elif self.type is float:
                if isinstance(value, (bool, np.bool_)):
                    raise ValueError
                out = float(value)
                if not math.isfinite(out):
                    raise ValueError
            else:
                if not isinstance(value, str):
                    raise ValueError
                out = value
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"{name}: expected {self.allowed()}, got {value!r}") from None
        if self.choices and out not in self.values:
            raise InputError(f"{name}: expected {self.allowed()}, got {value!r}")
        if (self.min is not None and out < self.min) or (self.max is not None and out > self.max):
            raise InputError(f"{name}: expected {self.allowed()}, got {value!r}")
        return out

    def parse(self, text: str, where: str = "") -> Any:
        """A command-line value (text) as this parameter's value, checked like ``check``."""
        text = str(text).strip()
        value: Any = text
        if self.type is bool:
            lowered = text.lower()
            truth = {"1": True, "true": True, "yes": True, "on": True, "0": False, "false": False, "no": False}
            truth["off"] = False
            value = truth.get(lowered, text)
        elif self.type in (int, float):
            try:
                value = int(text) if self.type is int else float(text)
            except ValueError:
                value = text
        return self.check(value, where)


@dataclass(frozen=True)
class Footprint:
    """How far a technique gathers light for one material, and with how many samples per pixel."""

    #: Kernel radius in scene units per channel (R, G, B); None for a technique without a kernel.
    radius_su: tuple[float, ...] | None = None
    #: Samples (or taps) per pixel; None when the technique does not sample.
    samples: int | None = None


def no_footprint(params: Mapping[str, Any]) -> Footprint:
    """The footprint of a local technique: no kernel, no samples."""
    return Footprint()


def profile_footprint(samples_param: str) -> Callable[[Mapping[str, Any]], Footprint]:
    """The footprint of a technique that gathers over the diffusion profile of d per channel
    (``d_su``): 16 d (``profiles.TRUNCATION``, where Cycles also cuts Burley's profile), with the
    sample count of parameter ``samples_param``."""

    def footprint(params: Mapping[str, Any]) -> Footprint:
        d = params.get("d_su")
        radius = None
        if d is not None:
            # A material's d (technique_params': a tuple of three) is read as it is, without NumPy.
            d3 = d if isinstance(d, tuple) and len(d) == 3 else np.broadcast_to(np.asarray(d, np.float64), (3,))
            radius = tuple(float(v) * TRUNCATION for v in d3)
        samples = params.get(samples_param)
        return Footprint(radius_su=radius, samples=None if samples is None else int(samples))

    return footprint


@dataclass(frozen=True)
class Technique:
    """Everything SSS Lab needs to know about one technique (see the module docstring)."""

    #: Identifier: the command line's ``--methods``, the layer names ``SSSLab.<name>.*``.
    name: str
    label: str
    #: One line, for the panel's drop-down and ``--help``.
    description: str
    #: Where its formulas come from: a section of docs/references.md and the paper.
    citation: str
    #: The pure function: keyword-only arrays in, float32 (H, W, 3) out (``core/pipeline/apply.py``).
    function: Callable[..., np.ndarray]
    #: True when it redistributes the diffuse light: its result replaces albedo x (Diffuse Direct +
    #: Indirect) on the material's pixels, and the albedo mode applies.
    scatters: bool
    #: True when it adds light the passes do not hold (from behind): its result is added, and a
    #: kernel of one pixel still changes the material.
    adds_light: bool
    #: Passes it reads, by their Blender 5.x names (``core/scene/passes.py``; ``THICKNESS``: the scene's
    #: thickness AOV). Combined and Material Index are always among them.
    passes: tuple[str, ...]
    #: The parameters a user may set (panel, command line, compare); defaults from the signature.
    params: tuple[Param, ...] = ()
    #: Passes it reads when the passes hold them (its keyword is then given, else left at its
    #: default); neither ``apply`` nor ``render`` requires them (another technique's passes bring
    #: them: the combined technique's Normal, Position and thickness AOV).
    optional_passes: tuple[str, ...] = ()
    #: ``compare``'s quality ladder, cheapest first: keyword arguments per run.
    qualities: tuple[Mapping[str, Any], ...] = ({},)
    #: Index into ``qualities`` of the run equal to the defaults (the summary picture shows it).
    default_quality: int = 0
    #: How far it gathers and with how many samples, from a material's parameters.
    footprint: Callable[[Mapping[str, Any]], Footprint] = no_footprint
    #: What ``compare`` calibrates: ``CALIBRATE_MAPPING``, a grid {parameter: values}, or None.
    calibration: str | Mapping[str, tuple[Any, ...]] | None = None
    #: Parameters that switch off the light it adds, so that the fidelity table measures its
    #: diffusion alone (a technique that scatters and adds light).
    diffusion_only: Mapping[str, Any] = field(default_factory=dict)
    #: Adjusts one material's parameters before it runs (may change them); returns notes for the
    #: plan, one line each. None: nothing to adjust.
    prepare: Callable[[dict[str, Any]], list[str]] | None = None
    #: What ``calibrate`` may fit per material (``core/study/fit.py``): names of ``core/pipeline/fit_params.py``'s
    #: ``PARAMETERS``, e.g. ("gain", "d_scale"); () when it has no fit (calibrate refuses it).
    fit: tuple[str, ...] = ()
    #: True when ``auto`` (``core/pipeline/auto.py``) may choose it; False: listed there as not a candidate
    #: (its learnt model then needs no coefficients for it).
    auto: bool = True
    #: ``core.pipeline.apply``'s route that runs it and composites its result in one compiled pass
    #: per material, the same bits as the generic route: ``composite(passes, scene, index, image,
    #: sss, gain, weight, params)`` -> (pixels not finite, pixels overflowed, pixels clamped), or
    #: None where it does not apply (``core.techniques.sta.technique.composite``). None: always the
    #: generic route (the technique's function, then the compositing). A route computes one
    #: function, which it names as its ``computes`` attribute: a spec made with another function
    #: (``dataclasses.replace``, a stand-in in a test) drops it and takes the generic route.
    composite: Callable[..., tuple[int, int, int] | None] | None = None

    def __post_init__(self) -> None:
        where = f"technique {self.name!r}"
        if self.composite is not None and getattr(self.composite, "computes", None) is not self.function:
            object.__setattr__(self, "composite", None)  # the route of another function
        if not (self.scatters or self.adds_light):
            raise TypeError(f"{where}: it must scatter light, add light, or both")
        unknown = [p for p in self.passes if p != THICKNESS and p not in PASSES]
        if unknown:
            raise TypeError(f"{where}: passes {unknown} are not in the pass table (core/scene/passes.py)")
        unknown = [p for p in self.optional_passes if p != THICKNESS and p not in PASSES]
        if unknown:
            raise TypeError(f"{where}: optional passes {unknown} are not in the pass table (core/scene/passes.py)")
        for needed in ("Combined", "Material Index"):
            if needed not in self.passes:
                raise TypeError(f"{where}: every technique reads {needed!r}; add it to its passes")
        sig = inspect.signature(self.function)
        filled = []
        for p in self.params:
            sp = sig.parameters.get(p.name)
            if sp is None or sp.kind is not inspect.Parameter.KEYWORD_ONLY:
                raise TypeError(f"{where}: parameter {p.name!r} is not a keyword-only argument of its function")
            if sp.default is inspect.Parameter.empty:
                raise TypeError(f"{where}: parameter {p.name!r} has no default in the function's signature")
            if p.default is not None and p.default != sp.default:  # (a spec copied with replace() has them)
                raise TypeError(f"{where}: parameter {p.name!r} declares a default; it belongs in the signature")
            filled.append(dataclasses.replace(p, default=sp.default))
        object.__setattr__(self, "params", tuple(filled))
        if not isinstance(self.fit, tuple) or not all(isinstance(n, str) for n in self.fit):
            raise TypeError(f"{where}: fit must be a tuple of parameter names, got {self.fit!r}")
        if len(set(self.fit)) != len(self.fit):
            raise TypeError(f"{where}: fit {self.fit} names a parameter twice")
        if not self.qualities or not 0 <= self.default_quality < len(self.qualities):
            raise TypeError(f"{where}: default_quality {self.default_quality} is not an index of its qualities")
        for quality in self.qualities:
            for key in quality:
                if key not in self.keywords:
                    raise TypeError(f"{where}: quality {dict(quality)} sets {key!r}, which its function does not take")

    @functools.cached_property
    def keywords(self) -> frozenset[str]:
        """The keyword arguments its function takes (read once: reading a signature costs some
        0.1 ms, and planning asks for it per material and candidate)."""
        sig = inspect.signature(self.function)
        kinds = (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
        return frozenset(p.name for p in sig.parameters.values() if p.kind in kinds)

    @property
    def defaults(self) -> dict[str, Any]:
        """Its parameters' defaults (from the function's signature)."""
        return {p.name: p.default for p in self.params}

    @property
    def reads_thickness(self) -> bool:
        """True when it reads the thickness AOV (it needs a baked thickness map)."""
        return THICKNESS in self.passes

    def param(self, name: str) -> Param:
        """Its parameter ``name``; InputError listing the allowed names otherwise."""
        for p in self.params:
            if p.name == name:
                return p
        raise InputError(f"{self.name} has no parameter {name!r}; its parameters: {', '.join(self.param_names)}")

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def check_params(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """``values`` checked against the parameter specs (types, ranges, choices); InputError
        naming the first bad key or value and what is allowed."""
        return {k: self.param(k).check(v, f"{self.name}.") for k, v in values.items()}

    def samples_per_pixel(self, params: Mapping[str, Any], lights: int) -> int:
        """What one pixel costs this technique with ``params`` (missing ones at their defaults),
        in a unit that does not depend on the machine: its samples or taps (``footprint``; SSSS:
        taps per pass), plus one evaluation per light when it adds light from behind; at least one.
        ``auto``'s work model and the report's samples axis count the same way."""
        per_pixel = self.footprint({**self.defaults, **params}).samples or 0
        if self.adds_light:
            per_pixel += max(int(lights), 1)
        return max(int(per_pixel), 1)

    def quality_label(self, quality: Mapping[str, Any]) -> str:
        """``Burley samples=16``: the label of one run of the quality ladder."""
        if not quality:
            return self.label
        return self.label + " " + ", ".join(f"{k.replace('n_', '')}={v}" for k, v in quality.items())

    @property
    def default_run(self) -> Mapping[str, Any]:
        """The quality ladder's run at the default quality."""
        return self.qualities[self.default_quality]
