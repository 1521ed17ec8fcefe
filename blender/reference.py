"""The Cycles reference rendered in parts, one seed each, for a render farm.

``render_reference_parts(scene, out_dir, seeds=..., samples=...)`` renders the scene as it is
(its own subsurface method), Combined only as the comparison reads it, once per seed, into
``reference_seed_#####.exr`` with a JSON beside it (samples, seed, frame, size, the scene's
fingerprint). ``core.study.reference`` merges the parts into one reference of the summed samples and
takes the noise floor from two halves of them; ``compare --reference`` uses the result.

The render settings are those of the comparison's own reference (adaptive sampling, denoising
and the animated seed off), so that a merged reference and a single one estimate the same image.
The scene is put back afterwards, also on failure.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable

import bpy

from ..core.base.errors import InputError, SSSLabError
from ..core.base.files import atomic_write, write_text
from ..core.base.progress import Progress, saved_line
from ..core.scene import exr
from ..core.study.reference import part_path, read_meta, sidecar
from .reference_cache import render_combined, scene_fingerprint
from .state import SceneState


def _unfinished(path: str, seed: int, wanted: dict) -> str | None:
    """Why the part at ``path`` is not a finished part of this job and must be rendered again (a
    file missing, a JSON that does not read, an EXR cut short or of another size than its JSON
    says, a JSON of another seed); None when it is one and is kept. InputError when it is a
    finished part of another job (other samples, size, frame or scene state): rendering over it
    would destroy that job's work, and keeping it would corrupt the merge."""
    meta_path = sidecar(path)
    for missing, other in ((path, meta_path), (meta_path, path)):
        if not os.path.isfile(missing):
            return f"no {os.path.basename(missing)} beside {os.path.basename(other)}"
    try:
        meta = read_meta(meta_path, required=("samples", "seed"))
    except InputError as exc:
        return str(exc)
    differ = {k: (meta.get(k), v) for k, v in wanted.items() if meta.get(k) != v}
    if differ:
        detail = "; ".join(f"{k} {old!r} there, {new!r} asked" for k, (old, new) in differ.items())
        raise InputError(
            f"{path} exists but was rendered differently ({detail}); render into another folder, or pass --overwrite"
        )
    if meta["seed"] != seed:
        return f"{os.path.basename(meta_path)} says seed {meta['seed']}, not {seed}"
    try:
        image = exr.read_passes(path)["Combined"]
    except (SSSLabError, OSError, ValueError, KeyError) as exc:  # cut short or damaged
        return " ".join(str(exc).split())
    if list(image.shape[1::-1]) != wanted["resolution"]:
        w, h = wanted["resolution"]
        return f"it is {image.shape[1]}x{image.shape[0]} pixels, its JSON says {w}x{h}"
    return None


def render_reference_parts(
    scene,
    out_dir: str,
    *,
    seeds: Iterable[int],
    samples: int,
    resolution: tuple[int, int] | None = None,
    frame: int | None = None,
    skip_existing: bool = False,
    overwrite: bool = False,
    log: Callable[[str], None] | None = print,
) -> list[str]:
    """Render one reference part per seed into ``out_dir``; returns the paths written.

    A part whose EXR and JSON both exist is kept with ``skip_existing`` when it is whole and of
    this job (``_unfinished``: the EXR reads whole at the size asked, its JSON agrees on samples,
    seed, size, frame and fingerprint), rendered again with a line saying why when it is not
    finished (cut short, a file missing), and refused when it is a finished part of another job;
    replaced with ``overwrite``; otherwise refused. All before anything renders.
    """
    say = log or (lambda _line: None)
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise InputError("seeds: expected at least one seed")
    if any(s < 0 for s in seeds) or len(set(seeds)) != len(seeds):
        raise InputError(f"seeds: expected distinct integers >= 0, got {seeds}")
    if not isinstance(samples, int) or isinstance(samples, bool) or samples < 1:
        raise InputError(f"samples: expected an integer >= 1, got {samples!r}")
    if skip_existing and overwrite:
        raise InputError("skip_existing and overwrite: choose one")
    if scene.camera is None:
        raise InputError(f"scene {scene.name!r} has no active camera; set one in Scene Properties > Camera")
    out_dir = os.path.abspath(os.fspath(out_dir))
    frame = scene.frame_current if frame is None else int(frame)
    render = scene.render
    size = (
        list(resolution)
        if resolution is not None
        else [
            render.resolution_x * render.resolution_percentage // 100,
            render.resolution_y * render.resolution_percentage // 100,
        ]
    )
    old_frame = scene.frame_current
    scene.frame_set(frame)
    try:
        fingerprint = scene_fingerprint(scene)
    finally:
        scene.frame_set(old_frame)
    wanted = {"samples": samples, "frame": frame, "resolution": size, "fingerprint": fingerprint}

    todo: list[tuple[int, str]] = []
    skipped: list[tuple[int, str]] = []
    again: dict[int, str] = {}  # seed: why its part is rendered again
    for seed in seeds:
        path = part_path(out_dir, seed)
        if skip_existing and (os.path.lexists(path) or os.path.lexists(sidecar(path))):
            why = _unfinished(path, seed, wanted)
            if why is None:
                skipped.append((seed, path))
            else:
                again[seed] = why
                todo.append((seed, path))
        elif not overwrite and (os.path.exists(path) or os.path.exists(sidecar(path))):
            existing = path if os.path.exists(path) else sidecar(path)
            raise FileExistsError(
                f"{existing} already exists; refusing to overwrite it (pass --skip-existing to keep finished parts, "
                "or --overwrite)"
            )
        else:
            todo.append((seed, path))
    os.makedirs(out_dir, exist_ok=True)
    progress = Progress(len(seeds))
    for seed, path in skipped:
        say(f"{progress.position()} seed {seed}: skipped, {os.path.basename(path)} exists ({progress.skip()})")

    written: list[str] = []
    with SceneState() as state:
        old_frame, old_subframe = scene.frame_current, scene.frame_subframe
        state.on_restore(lambda: scene.frame_set(old_frame, subframe=old_subframe))
        scene.frame_set(frame)
        for seed, path in todo:
            if seed in again:
                say(f"seed {seed}: {os.path.basename(path)} is not a finished part ({again[seed]}): rendering it again")
            say(f"{progress.position()} seed {seed}: rendering {size[0]}x{size[1]}, {samples} samples, frame {frame}")
            timing: list[float] = []

            def render_to(tmp, seed=seed, timing=timing):
                timing.append(
                    render_combined(scene, samples=samples, seed=seed, resolution=resolution, path=tmp, state=state)
                )

            # Written under a temporary name: a cancelled task leaves no part that looks finished.
            atomic_write(path, render_to)
            seconds = timing[0]
            written.append(path)
            say(saved_line(path))
            meta = dict(wanted, seed=seed, seconds=seconds, scene=scene.name, blender=bpy.app.version_string)
            write_text(sidecar(path), json.dumps(meta, indent=2) + "\n")
            written.append(sidecar(path))
            say(saved_line(sidecar(path)))
            say(f"seed {seed} done in {seconds:.2f} s ({progress.finish()})")
    return written
