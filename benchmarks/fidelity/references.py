"""The fidelity suite's stored Cycles references: render them, store them, load them.

Each scene's reference is Cycles random walk (the scene's own subsurface method) at
``SAMPLES`` samples, adaptive sampling and denoising off, rendered twice with seeds 0 and 1
(docs/references.md §8: the second seed measures the noise floor). Both are stored as half-float
RGB in ``references/<scene>.exr`` (ZIP compressed, layers ``seed0`` and ``seed1``; half keeps
three significant digits, far below the Monte Carlo noise, and the values stay far below 65504)
and ``references/manifest.json`` records per scene the fingerprint of the scene as built
(``scene_fingerprint``: geometry, materials, lights, camera, world, render settings, Blender
version), the samples, seeds, resolution and render times.

Regenerate (all scenes or some; a few minutes per scene on a 2-core machine)::

    nice -n 10 .venv/bin/python -m benchmarks.fidelity.references [SCENE ...] [--samples 1024]

Held-out scenes (a module whose ``SCENES`` maps names to ``scenes.SuiteScene``) get their
references the same way, into their own folder, and are then scored by the same runner::

    python -m benchmarks.fidelity.references --scenes-module MODULE --store DIR
    python -m benchmarks.fidelity.run --scenes-module MODULE --store DIR --out ... --table ... --grid ...

``load`` refuses a reference whose fingerprint differs from the scene's: a scene edited
without re-rendering fails loudly instead of being scored against a picture of another scene.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
STORE = os.path.join(HERE, "references")
#: Frame B of every scene (``scenes.frame_b``, camera and lights moved): its references, rendered by
#: ``REGENERATE_B`` as the suite's (``SAMPLES_B`` samples, seeds 0 and 1); ``benchmarks/fit.py``
#: scores on them the fits made on frame A.
STORE_B = os.path.join(HERE, "references_b")
SAMPLES_B = 1024
REGENERATE_B = (
    "nice -n 10 .venv/bin/python -m benchmarks.fidelity.references {name} --scenes-module benchmarks.fidelity.frame_b"
    " --store benchmarks/fidelity/references_b --samples 1024"
)
MANIFEST = os.path.join(STORE, "manifest.json")
SAMPLES = 1024
SEEDS = (0, 1)
REGENERATE = "nice -n 10 .venv/bin/python -m benchmarks.fidelity.references {name}"


def _regenerate(store: str) -> str:
    """The command that renders a store's references again ({name}: the scenes)."""
    same = os.path.abspath(store) == os.path.abspath(STORE_B)
    return REGENERATE_B if same else REGENERATE


class StaleReferenceError(RuntimeError):
    """A stored reference does not match the scene (or there is none)."""


def read_manifest(path: str = MANIFEST) -> dict:
    if not os.path.isfile(path):
        return {"scenes": {}}
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def exr_path(name: str, store: str = STORE) -> str:
    return os.path.join(store, f"{name}.exr")


def write_half(path: str, layers: dict[str, np.ndarray]) -> None:
    """Write RGB ``layers`` (name -> (H, W, 3) float) as half floats, ZIP compressed, atomically."""
    import OpenEXR

    from sss_lab.core.base.files import atomic_write

    channels = {}
    for name, image in layers.items():
        img = np.asarray(image, dtype=np.float32)[..., :3]
        if not np.isfinite(img).all() or np.abs(img).max() >= 65504:
            raise ValueError(f"{path}: layer {name} is not finite or exceeds the half-float range")
        for i, c in enumerate("RGB"):
            channels[f"{name}.{c}"] = np.ascontiguousarray(img[..., i].astype(np.float16))
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    atomic_write(path, lambda tmp: OpenEXR.File(header, channels).write(tmp))


def read_half(path: str) -> dict[str, np.ndarray]:
    """The layers of a file ``write_half`` wrote, as float32 (H, W, 3)."""
    import OpenEXR

    out: dict[str, dict[str, np.ndarray]] = {}
    with OpenEXR.File(path, separate_channels=True) as f:
        for full, channel in f.channels().items():
            layer, _, c = full.rpartition(".")
            out.setdefault(layer, {})[c] = np.asarray(channel.pixels, dtype=np.float32)
    return {k: np.stack([v["R"], v["G"], v["B"]], axis=-1) for k, v in out.items()}


def load(name: str, fingerprint: str, *, store: str = STORE) -> tuple[np.ndarray, np.ndarray, dict]:
    """(seed 0 image, seed 1 image, manifest entry) of scene ``name``; StaleReferenceError when
    there is no stored reference or when its fingerprint is not ``fingerprint``."""
    entry = read_manifest(os.path.join(store, "manifest.json"))["scenes"].get(name)
    path = exr_path(name, store)
    if entry is None or not os.path.isfile(path):
        raise StaleReferenceError(
            f"fidelity scene {name!r} has no stored reference in {store}; render it:"
            f" {_regenerate(store).format(name=name)}"
        )
    if entry["fingerprint"] != fingerprint:
        raise StaleReferenceError(
            f"fidelity scene {name!r} no longer matches its stored reference (scene fingerprint {fingerprint[:12]},"
            f" reference {entry['fingerprint'][:12]}, rendered with Blender {entry.get('blender')}): the scene or"
            f" Blender changed since the reference was rendered. Render it again:"
            f" {_regenerate(store).format(name=name)}"
        )
    layers = read_half(path)
    return layers["seed0"], layers["seed1"], entry


def fingerprint(scene) -> str:
    from sss_lab.blender.reference_cache import scene_fingerprint

    return scene_fingerprint(scene)


def render(name: str, *, samples: int = SAMPLES, scenes=None, store: str = STORE, log=print) -> dict:
    """Build scene ``name``, render both seeds and store them; returns the manifest entry."""
    import bpy

    from sss_lab.blender.reference_cache import cached_reference

    from . import scenes as suite

    table = suite.SCENES if scenes is None else scenes
    scene = suite.build(name, table)
    suite.prepare(scene)
    fp = fingerprint(scene)
    images, seconds = {}, []
    with tempfile.TemporaryDirectory(prefix="sss_lab_fidelity_") as tmp:
        for seed in SEEDS:
            img, secs, _ = cached_reference(
                scene,
                tmp,
                samples=samples,
                seed=seed,
                resolution=suite.RESOLUTION,
                method=None,
                log=lambda line: log(f"{name}: {line}"),
                fingerprint=fp,
            )
            images[f"seed{seed}"] = img
            seconds.append(round(secs, 2))
    os.makedirs(store, exist_ok=True)
    write_half(exr_path(name, store), images)
    entry = {
        "fingerprint": fp,
        "kind": table[name].kind,
        "samples": samples,
        "seeds": list(SEEDS),
        "resolution": list(suite.RESOLUTION),
        "blender": bpy.app.version_string,
        "render_seconds": seconds,
        "rendered_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    manifest_path = os.path.join(store, "manifest.json")
    manifest = read_manifest(manifest_path)  # read again: other processes may have added scenes
    manifest["scenes"][name] = entry
    manifest["scenes"] = dict(sorted(manifest["scenes"].items()))
    manifest["command"] = _regenerate(store).format(name="[SCENE ...]")
    from sss_lab.core.base.files import write_text

    write_text(manifest_path, json.dumps(manifest, indent=1) + "\n")
    log(f"Saved: {exr_path(name, store)} ({seconds} s)")
    return entry


def main(argv=None) -> int:
    import importlib

    from . import scenes as suite

    parser = argparse.ArgumentParser(description="Render and store the fidelity suite's Cycles references.")
    parser.add_argument("names", nargs="*", help=f"scenes (default: all of {', '.join(suite.SCENES)})")
    parser.add_argument("--samples", type=int, default=SAMPLES, help=f"Cycles samples (default {SAMPLES})")
    parser.add_argument("--missing", action="store_true", help="only scenes without a matching stored reference")
    parser.add_argument(
        "--scenes-module", help="a module with SCENES built the suite's way (held-out scenes; default: the suite)"
    )
    parser.add_argument("--store", default=STORE, help=f"folder of the references (default {STORE})")
    args = parser.parse_args(argv)
    table = importlib.import_module(args.scenes_module).SCENES if args.scenes_module else suite.SCENES
    names = args.names or list(table)
    unknown = [n for n in names if n not in table]
    if unknown:
        parser.error(f"unknown scene(s) {unknown}; expected: {', '.join(table)}")
    for name in names:
        if args.missing:
            scene = suite.build(name, table)
            suite.prepare(scene)
            try:
                load(name, fingerprint(scene), store=args.store)
                print(f"{name}: stored reference matches, skipped")
                continue
            except StaleReferenceError:
                pass
        render(name, samples=args.samples, scenes=table, store=args.store)
    return 0


if __name__ == "__main__":
    sys.exit(main())
