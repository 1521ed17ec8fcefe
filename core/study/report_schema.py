"""The comparison report as typed data: ``Report`` and its ``Entry`` rows, with their JSON form.

``blender.compare`` measures and ``core.study.report.write_report`` writes ``metrics.json``; readers (the
command line, the operator, scripts) take it as a ``Report`` (``Report.from_dict`` on what
``compare`` returns, or ``Report.read(path)`` on the file) instead of reading a dict with
``.get``. Fields a newer writer adds that this schema does not name are kept in ``extra``, so
that ``to_dict`` gives back what was read.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any

from ..base.errors import InputError
from ..base.jsonfile import read_json

#: The kinds of row: the passes' own image, a technique run, a Cycles render, an EEVEE render (or its
#: SSS effect on Cycles' image without scattering).
ENTRY_KINDS = ("baseline", "technique", "cycles", "eevee")


@dataclass
class Entry:
    """One measured image of the report."""

    name: str
    kind: str
    #: rel_rmse, ssim, ... (``core.study.metrics.compare_images``); None where nothing could be measured.
    metrics: dict[str, float | None]
    #: Seconds: ``total`` end to end, ``apply`` for a technique's own run, ...
    time_s: dict[str, float | None]
    technique: str | None = None
    quality: dict[str, Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    _NAMED = ("name", "kind", "metrics", "time_s", "technique", "quality")

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Entry:
        missing = [k for k in ("name", "kind", "metrics", "time_s") if k not in data]
        if missing:
            raise ValueError(f"report entry {data.get('name', '?')!r}: missing {', '.join(missing)}")
        if data["kind"] not in ENTRY_KINDS:
            raise ValueError(f"report entry {data['name']!r}: kind {data['kind']!r} is not one of {ENTRY_KINDS}")
        return cls(
            name=str(data["name"]),
            kind=str(data["kind"]),
            metrics=dict(data["metrics"]),
            time_s=dict(data["time_s"]),
            technique=data.get("technique"),
            quality=dict(data["quality"]) if data.get("quality") is not None else None,
            extra={k: v for k, v in data.items() if k not in cls._NAMED},
        )

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "kind": self.kind, "metrics": self.metrics, "time_s": self.time_s}
        if self.technique is not None:
            out["technique"] = self.technique
        if self.quality is not None:
            out["quality"] = self.quality
        out.update(self.extra)
        return out

    @property
    def rel_rmse(self) -> float | None:
        return self.metrics.get("rel_rmse")


@dataclass
class Report:
    """The comparison of one scene: its rows, the error/time Pareto front, and what is missing."""

    entries: list[Entry]
    #: Names of the entries on the error/time Pareto front.
    pareto: list[str]
    #: False when a technique or a measurement could not run (``notes`` say which and why).
    complete: bool
    notes: list[str]
    #: The reference's own noise (two seeds), the floor under which an error means nothing.
    noise_floor: dict[str, float | None]
    scene: dict[str, Any] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)
    #: Every other section (timings, costs, fidelity, calibration, summary, grid, version ...).
    extra: dict[str, Any] = field(default_factory=dict)

    _NAMED = ("entries", "pareto", "complete", "notes", "noise_floor", "scene", "settings")

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Report:
        if not isinstance(data, dict) or "entries" not in data:
            raise ValueError("not a comparison report: expected a JSON object with 'entries'")
        return cls(
            entries=[Entry.from_dict(e) for e in data["entries"]],
            pareto=list(data.get("pareto", [])),
            complete=bool(data.get("complete", False)),
            notes=list(data.get("notes", [])),
            noise_floor=dict(data.get("noise_floor") or {}),
            scene=dict(data.get("scene") or {}),
            settings=dict(data.get("settings") or {}),
            extra={k: v for k, v in data.items() if k not in cls._NAMED},
        )

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "scene": self.scene,
            "settings": self.settings,
            "noise_floor": self.noise_floor,
            "entries": [e.to_dict() for e in self.entries],
            "pareto": self.pareto,
            "notes": self.notes,
            "complete": self.complete,
        }
        out.update(self.extra)
        return out

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, sort_keys=True)  # as core.study.report writes metrics.json

    @classmethod
    def read(cls, path: str | os.PathLike[str]) -> Report:
        """The report in ``path`` (a ``metrics.json``); ValueError naming the file otherwise."""
        try:
            return cls.from_dict(read_json(path, "a report (metrics.json)"))
        except InputError:
            raise
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{os.fspath(path)}: {exc}") from None

    def entry(self, name: str) -> Entry:
        for e in self.entries:
            if e.name == name:
                return e
        raise KeyError(f"no entry {name!r} in the report; it has: {', '.join(e.name for e in self.entries)}")

    @property
    def best_techniques(self) -> list[Entry]:
        """The technique runs on the Pareto front, in report order."""
        front = set(self.pareto)
        return [e for e in self.entries if e.kind == "technique" and e.name in front]
