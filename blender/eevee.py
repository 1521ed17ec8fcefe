"""EEVEE, Blender's real-time renderer, as a peer of the techniques in ``compare``.

EEVEE's subsurface scattering is a screen-space Burley gather of its own (docs/references.md §12):
what users ask is how far it is from Cycles' random walk on their scene. EEVEE's other shading
differs from Cycles' too (shadows, indirect light, the world), so it is measured twice
(``blender/compare.py``):

- **as it renders**: EEVEE's image, scattering on, against the Cycles reference;
- **its SSS effect**: EEVEE with scattering minus EEVEE without (every subsurface material
  rendered with Subsurface Weight 0, as the passes are), added to Cycles' image without scattering
  (the passes' Combined) and scored like a technique's image: the share of the no-SSS error it
  removes is the share of Cycles' SSS effect it reproduces (the error of EEVEE's effect against
  Cycles' effect, relative to Cycles' effect).

``cached_eevee`` renders with the scene's own EEVEE settings (samples as given, or the scene's),
at the comparison's size, and keeps the image on disk like the Cycles references
(``blender.reference_cache``), keyed by the scene's fingerprint and every EEVEE setting. Rendering
needs an OpenGL context: headless Blender makes one through EGL (software OpenGL on a machine
without a GPU: seconds to a minute a frame, the first compiling the shaders); where none can be
made the render raises ``EeveeUnavailable`` and ``compare`` says so in one line and measures the
rest.
"""

from __future__ import annotations

import hashlib
import json
import os
import time

import bpy
import numpy as np

from ..core.base import files, memory
from ..core.scene import exr
from . import compat
from .reference_cache import read_cached_image
from .render_passes import zero_subsurface
from .state import SceneState

#: Pixels a side of the untimed frame that compiles EEVEE's shaders before the timed one.
WARM_UP = 8


class EeveeUnavailable(RuntimeError):
    """EEVEE could not render here (no OpenGL context, or the render failed): the message says why."""


def settings_digest(scene) -> str:
    """A hash of the scene's EEVEE settings (every plain property of ``scene.eevee``): they change
    EEVEE's image and are no part of the Cycles fingerprint."""
    eevee = scene.eevee
    values = {}
    for prop in eevee.bl_rna.properties:
        if prop.identifier == "rna_type" or prop.type in {"POINTER", "COLLECTION"}:
            continue
        value = getattr(eevee, prop.identifier)
        values[prop.identifier] = list(value) if hasattr(value, "__len__") and not isinstance(value, str) else value
    return hashlib.sha256(json.dumps(values, sort_keys=True, default=repr).encode()).hexdigest()[:16]


def render_eevee(scene, *, samples: int | None, resolution, sss: bool, path: str, state: SceneState) -> float:
    """Render ``scene`` with EEVEE to a float32 multilayer EXR at ``path`` (scattering off when
    ``sss`` is false: every subsurface material as plain diffuse); returns the render's seconds.
    ``samples`` None keeps the scene's own. Raises ``EeveeUnavailable`` when EEVEE cannot render."""
    render = scene.render
    state.set(render, "engine", compat.eevee_engine())
    state.set(render, "use_compositing", False)
    if samples is not None:
        state.set(scene.eevee, "taa_render_samples", samples)
    if render.use_border:  # the whole frame, as the Cycles images it is compared with
        state.set(render, "use_border", False)
    if resolution is not None:
        state.set(render, "resolution_x", resolution[0])
        state.set(render, "resolution_y", resolution[1])
        state.set(render, "resolution_percentage", 100)
    if not sss:
        zero_subsurface(state, scene)
    memory.check_frame(
        render.resolution_x * render.resolution_percentage // 100,
        render.resolution_y * render.resolution_percentage // 100,
        4,
        "the EEVEE render",
    )
    start = time.perf_counter()
    try:
        bpy.ops.render.render(scene=scene.name)
    except RuntimeError as exc:
        raise EeveeUnavailable(f"EEVEE could not render here ({' '.join(str(exc).split())[:200]})") from None
    seconds = time.perf_counter() - start
    result = bpy.data.images.get("Render Result")
    if result is None:
        raise EeveeUnavailable("EEVEE could not render here (it left no Render Result: no OpenGL context?)")
    settings = render.image_settings
    fmt = compat.image_format_state(settings)
    state.on_restore(lambda: compat.restore_image_format(settings, fmt))
    compat.set_multilayer_exr(settings)
    result.save_render(filepath=path, scene=scene)
    return seconds


def cached_eevee(
    scene,
    cache_dir: str,
    *,
    samples: int | None,
    resolution,
    sss: bool,
    fingerprint: str,
    log=print,
    warm_up: bool = True,
) -> tuple[np.ndarray, float, bool]:
    """EEVEE's image of ``scene`` (scattering on or off), from the cache when neither the scene
    (``fingerprint``, ``blender.reference_cache.scene_fingerprint``) nor its EEVEE settings changed.
    Returns (RGBA float32 image, render seconds as measured when rendered, from cache). The scene
    is left as it was. ``warm_up`` False leaves out the untimed frame that compiles the shaders
    first (for a caller that does not use the seconds)."""
    log = log or (lambda _line: None)
    what = f"EEVEE {samples or scene.eevee.taa_render_samples} samples, scattering {'on' if sss else 'off'}"
    key = hashlib.sha256(
        json.dumps(
            [fingerprint, settings_digest(scene), samples, list(resolution or []), sss, bpy.app.version_string]
        ).encode()
    ).hexdigest()[:24]
    path = os.path.join(cache_dir, f"eevee_{key}.exr")
    meta_path = path[:-4] + ".json"
    cached = read_cached_image(path, meta_path, log)
    if cached is not None:
        log(f"{what}: cached ({os.path.basename(path)})")
        return cached[0], cached[1], True
    log(f"{what}: rendering")
    os.makedirs(cache_dir, exist_ok=True)
    if resolution is None:  # the scene's own size, kept after the warm-up frame's
        r = scene.render
        resolution = (r.resolution_x * r.resolution_percentage // 100, r.resolution_y * r.resolution_percentage // 100)
    with SceneState() as state, files.temporary_beside(path, suffix=".exr") as tmp:
        # First an untimed frame of WARM_UP pixels with one sample: EEVEE compiles the scene's shaders on
        # its first frame (there 33 s of a 46 s first 96 px frame), which is no part of what a frame costs.
        if warm_up:
            render_eevee(scene, samples=1, resolution=(WARM_UP, WARM_UP), sss=sss, path=tmp, state=state)
        seconds = render_eevee(scene, samples=samples, resolution=resolution, sss=sss, path=tmp, state=state)
        image = exr.read_passes(tmp)["Combined"]
        files.move_into_place(tmp, path)
    files.write_text(meta_path, json.dumps({"seconds": seconds, "samples": samples, "sss": sss, "engine": "EEVEE"}))
    return image, seconds, False
