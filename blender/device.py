"""Render threads and the Cycles device, set for one job and put back after (farm options).

``set_threads_and_device(state, scene, threads=..., device=...)`` is what the command line's
``--threads`` and ``--device`` do for every command that renders with Blender.
"""

from __future__ import annotations

import bpy

from ..core.base.errors import InputError

#: Cycles devices: the CPU, or a GPU back-end of the Cycles preferences.
DEVICES = ("CPU", "CUDA", "OPTIX", "HIP", "ONEAPI", "METAL")


def set_threads_and_device(state, scene, *, threads: int | None = None, device: str | None = None) -> str | None:
    """Set render threads (0: one per core, as Blender's ``-t 0``) and the Cycles device through
    ``state`` (a ``SceneState``: restored with it). Returns a line saying what was chosen, or None.

    InputError for a device not in ``DEVICES`` or one this machine does not have (naming the
    devices Cycles sees).
    """
    said = []
    if threads is not None:
        if not isinstance(threads, int) or isinstance(threads, bool) or threads < 0 or threads > 1024:
            raise InputError(f"threads: expected an integer from 0 (one per core) to 1024, got {threads!r}")
        render = scene.render
        if threads == 0:
            state.set(render, "threads_mode", "AUTO")
        else:
            state.set(render, "threads_mode", "FIXED")
            state.set(render, "threads", threads)
        said.append("one render thread per core" if threads == 0 else f"{threads} render thread(s)")
    if device is not None:
        device = str(device).upper()
        if device not in DEVICES:
            raise InputError(f"device: expected one of {', '.join(DEVICES)}, got {device!r}")
        if device == "CPU":
            state.set(scene.cycles, "device", "CPU")
        else:
            prefs = bpy.context.preferences.addons["cycles"].preferences
            prefs.refresh_devices()
            found = [d for d in prefs.devices if d.type == device]
            if not found:
                seen = sorted({d.type for d in prefs.devices}) or ["none"]
                raise InputError(
                    f"device: Cycles finds no {device} device on this machine (it sees: {', '.join(seen)}); "
                    "use --device CPU or check the GPU driver"
                )
            state.set(prefs, "compute_device_type", device)
            for d in prefs.devices:
                if d.use != (d.type == device):
                    state.set(d, "use", d.type == device)
            state.set(scene.cycles, "device", "GPU")
        said.append(f"Cycles device {device}")
    return ", ".join(said) or None
