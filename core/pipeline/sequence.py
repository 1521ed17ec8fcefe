"""Files and frame sequences: what ``python -m sss_lab apply`` does, without the printing.

``apply_file`` reads one passes EXR and its scene description, plans and applies the
techniques (``core.pipeline.plan``, ``core.pipeline.apply``) and writes a new EXR; ``sequence_frames`` and
``frame_path`` turn a ``passes_####.exr`` pattern into the files of a sequence.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field

from ..scene.scene import SceneDescription
from ..techniques.registry import get_spec
from .apply import apply
from .plan import plan

_HASHES = re.compile(r"#+")


#: The most frames one run takes: a range beyond it is a typing slip (1-100000000), not a job.
MAX_FRAMES = 100_000


def parse_frames(text: str) -> list[int]:
    """``"1-5"``, ``"7"``, ``"1-3,8"``, ``"1-9:2"`` -> sorted frame numbers (inclusive ranges;
    ``:N`` every Nth frame, as Open Job Description writes a range with a step), at most
    ``MAX_FRAMES`` of them (checked before any list is built)."""
    frames: set[int] = set()
    total = 0
    for chunk in str(text).split(","):
        chunk = chunk.strip()
        m = re.fullmatch(r"(-?\d+)(?:\s*(?:-|\.\.)\s*(-?\d+)(?:\s*:\s*(\d+))?)?", chunk)
        if not m:
            raise ValueError(f"frames: {chunk!r} is not a frame or a range like 1-10 or 1-10:2")
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
        step = int(m.group(3)) if m.group(3) is not None else 1
        if b < a:
            raise ValueError(f"frames: range {chunk!r} ends before it starts")
        if step < 1:
            raise ValueError(f"frames: step of {chunk!r} must be 1 or more")
        total += (b - a) // step + 1
        if total > MAX_FRAMES:
            raise ValueError(
                f"frames: {text!r} holds more than {MAX_FRAMES} frames, the most one run takes; split the range, "
                "or leave --frames out to take every existing file"
            )
        frames.update(range(a, b + 1, step))
    return sorted(frames)


def is_sequence(path: str) -> bool:
    """True when ``path`` holds a ``#`` frame pattern (``passes_####.exr``)."""
    return "#" in os.path.basename(os.fspath(path))


def frame_path(pattern: str, frame: int) -> str:
    """Replace the last run of ``#`` in the file name by ``frame``, zero-padded to its length
    (as Blender names rendered frames; more digits when the frame needs them)."""
    folder, name = os.path.split(os.fspath(pattern))
    runs = list(_HASHES.finditer(name))
    if not runs:
        return os.fspath(pattern)
    run = runs[-1]
    number = f"-{abs(frame):0{run.end() - run.start()}d}" if frame < 0 else f"{frame:0{run.end() - run.start()}d}"
    return os.path.join(folder, name[: run.start()] + number + name[run.end() :])


def sequence_frames(pattern: str, frames: list[int] | None = None) -> list[tuple[int | None, str]]:
    """The (frame, path) pairs of ``pattern``: the given frames, or every existing file that
    matches the pattern, in frame order. A path without ``#`` is one file with frame None."""
    pattern = os.fspath(pattern)
    if not is_sequence(pattern):
        if frames:
            raise ValueError(f"--frames needs a frame pattern with # in the file name, got {pattern!r}")
        return [(None, pattern)]
    if frames:
        return [(f, frame_path(pattern, f)) for f in frames]
    folder, name = os.path.split(pattern)
    run = list(_HASHES.finditer(name))[-1]
    regex = re.compile(
        re.escape(name[: run.start()]) + rf"(-?\d{{{run.end() - run.start()},}})" + re.escape(name[run.end() :]) + r"\Z"
    )
    found = []
    for entry in os.listdir(folder or "."):
        m = regex.match(entry)
        if m:
            found.append((int(m.group(1)), os.path.join(folder, entry)))
    if not found:
        raise FileNotFoundError(f"no file matches the frame pattern {pattern!r}")
    return sorted(found)


def default_output(path: str) -> str:
    """``passes.exr`` -> ``passes.sss.exr`` (beside the input)."""
    stem, _ = os.path.splitext(os.fspath(path))
    return stem + ".sss.exr"


def sidecar_path(path: str) -> str:
    """The scene description written beside a passes file: same stem, ``.json``."""
    stem, _ = os.path.splitext(os.fspath(path))
    return stem + ".json"


def load_scene(exr_path: str, scene_path: str | None = None) -> SceneDescription:
    """The scene description for ``exr_path``: ``scene_path`` if given, else the sidecar JSON."""
    path = scene_path or sidecar_path(exr_path)
    if not os.path.isfile(path):
        hint = "" if scene_path else " (the render writes it beside the EXR; or pass --description PATH)"
        raise FileNotFoundError(f"{path}: no scene description{hint}")
    return read_scene_file(path)


def read_scene_file(path: str) -> SceneDescription:
    """A scene description JSON file, checked (``SceneDescription.from_dict``); InputError names
    the file and what is wrong, also for a file that is not JSON text at all (an EXR, say)."""
    from ..base.errors import InputError
    from ..scene.exr import EXR_MAGIC

    with open(path, "rb") as fh:
        raw = fh.read()
    if raw.startswith(EXR_MAGIC):
        raise InputError(f"{path}: is an OpenEXR file, not a scene description; pass the .json written beside the EXR")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(
            f"{path}: not a scene description (not UTF-8 text: byte {exc.start}); pass the .json written beside the EXR"
        ) from None
    try:
        return SceneDescription.from_json(text)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None


@dataclass
class FileResult:
    """What ``apply_file`` did with one passes file."""

    path: str
    out_path: str
    scene: SceneDescription | None = None
    plans: dict = field(default_factory=dict)
    #: Techniques not run, with the reason (a missing pass when all techniques were asked for).
    skipped: dict = field(default_factory=dict)
    #: True when no material of the scene scatters: nothing is written.
    nothing_to_do: bool = False
    written: bool = False


def apply_file(
    path: str,
    techniques: list[str],
    *,
    out_path: str | None = None,
    scene: SceneDescription | None = None,
    scene_path: str | None = None,
    albedo_mode: str = "post",
    explain: bool = False,
    overwrite: bool = False,
    skip_missing: bool = False,
    view_layer: str | None = None,
    mapping=None,
    max_error: float | None = None,
    auto_rungs: bool = False,
    auto_keep: dict | None = None,
    params: Mapping[str, Mapping] | None = None,
    **options,
) -> FileResult:
    """Apply ``techniques`` to one passes file and write ``out_path`` (default ``<stem>.sss.exr``).

    The output holds every layer of the input (float32) plus, per technique,
    ``SSSLab.<technique>.Image`` and ``SSSLab.<technique>.SSS``; its header keeps the input's
    metadata and adds the scene description (``sss_lab.scene``, JSON). With ``explain`` it only
    plans. When no material scatters, nothing is written (``nothing_to_do``). With
    ``skip_missing`` a technique whose passes are missing is skipped (reason in ``skipped``)
    instead of raising, unless every technique is. The technique ``auto`` chooses one per material
    (``core/pipeline/auto.py``, within ``max_error`` of the best predicted error; ``auto_rungs``: the
    rungs of the techniques' quality ladders are candidates too) and writes
    ``SSSLab.auto.Image`` and ``SSSLab.auto.SSS``; ``auto_keep`` ({material: technique}, an
    earlier frame's ``AutoPlan.chosen``) keeps that choice. ``params``: {technique: {parameter:
    value}} (``core.techniques.registry.parse_params``), checked against each spec; ``options`` go to
    every technique.
    """
    from ..scene.exr import MissingPassError, passes_from_contents, read_layers, write_layers
    from . import auto as _auto

    path = os.fspath(path)
    out_path = os.fspath(out_path) if out_path else default_output(path)
    if os.path.abspath(out_path) == os.path.abspath(path):
        raise FileExistsError(f"{out_path} is the input file; refusing to overwrite it")
    # The scene description is an input too (sidecar or --description): never written over, however spelled.
    inputs = [path, scene_path or sidecar_path(path)]
    for source in inputs:
        if os.path.exists(out_path) and os.path.exists(source) and os.path.samefile(out_path, source):
            raise FileExistsError(f"{out_path} is an input of this computation ({source}); refusing to overwrite it")
    if not out_path.lower().endswith(".exr"):
        raise ValueError(f"--out {out_path!r}: the output is a multilayer OpenEXR file; give it the .exr suffix")
    result = FileResult(path=path, out_path=out_path)
    contents = read_layers(path)
    passes = passes_from_contents(contents, view_layer)
    per_technique = {t: get_spec(t).check_params((params or {}).get(t, {})) for t in techniques if t != _auto.AUTO}
    result.scene = scene = scene if scene is not None else load_scene(path, scene_path)
    h, w = passes.shape
    if (scene.camera.width_px, scene.camera.height_px) != (w, h):
        from ..base.errors import InputError

        raise InputError(
            f"{inputs[1] if scene_path or os.path.exists(inputs[1]) else 'the scene description'}: it describes "
            f"a {scene.camera.width_px}x{scene.camera.height_px} render, but {path} is {w}x{h}: they come from "
            "different renders; pass the JSON written with these passes (--description)"
        )
    for technique in techniques:
        if technique == _auto.AUTO:
            if options:
                raise ValueError(f"auto chooses each technique's parameters itself; it takes no {', '.join(options)}")
            limit = _auto.DEFAULT_MAX_ERROR if max_error is None else max_error
            result.plans[technique] = _auto.choose(
                passes,
                scene,
                max_error=limit,
                albedo_mode=albedo_mode,
                mapping=mapping,
                keep=auto_keep,
                rungs=auto_rungs,
            )
            continue
        try:
            run_options = {**options, **per_technique[technique]}
            result.plans[technique] = plan(
                passes, scene, technique, albedo_mode=albedo_mode, mapping=mapping, **run_options
            )
        except MissingPassError as exc:
            if not skip_missing:
                raise
            result.skipped[technique] = str(exc)
    if not result.plans:
        raise MissingPassError("none of the techniques can run on these passes:\n" + "\n".join(result.skipped.values()))
    if not any(p.scattering for p in result.plans.values()):
        result.nothing_to_do = True
        return result
    if explain:
        return result
    if os.path.isdir(out_path):
        raise FileExistsError(f"{out_path} is a folder; give the output a file name (--out FOLDER/NAME.exr)")
    if os.path.exists(out_path) and not overwrite:
        raise FileExistsError(f"{out_path} already exists; refusing to overwrite it (use --overwrite or --out)")
    layers = dict(contents.layers)
    channels = dict(contents.channels)
    for technique, p in result.plans.items():
        if technique == _auto.AUTO:
            new = _auto.apply_auto(passes, scene, prepared=p)
        else:
            new = apply(passes, scene, technique, albedo_mode=albedo_mode, prepared=p)
        for name in new:
            channels.pop(name, None)
        layers.update(new)
    header = dict(contents.header)
    header["sss_lab.scene"] = scene.to_json()
    header["sss_lab.methods"] = ",".join(result.plans)
    header["sss_lab.albedo_mode"] = albedo_mode
    write_layers(
        out_path, layers, header, channels=channels, overwrite=overwrite, inputs=inputs, windows=contents.windows
    )
    result.written = True
    return result
