"""Will a frame fit in memory? A check before a render that could not (no Blender needed).

A render at a size that cannot fit (65536 x 65536 is a valid Blender resolution: some 200 GB of
float32 passes) would otherwise run until the machine swaps or the process is killed, with no
word from SSS Lab. Before each render the frame's buffers are estimated - ``channels`` float32
values per pixel, twice (the renderer's buffers and the copy SSS Lab reads back) - and compared
with the memory the operating system says is available; a frame that cannot fit is refused with
the numbers and what to do. Where the available memory cannot be read, nothing is checked.
"""

from __future__ import annotations

import os

from .errors import InputError

#: Copies of the frame's buffers a render holds at once: the renderer's, and SSS Lab's copy of them.
COPIES = 2


def available_bytes() -> int | None:
    """Memory available to a new allocation, in bytes: Linux's MemAvailable, else the free
    physical pages (``os.sysconf``); None where neither can be read."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        pages, size = os.sysconf("SC_AVPHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
    return int(pages) * int(size) if pages > 0 and size > 0 else None


def frame_bytes(width: int, height: int, channels: int) -> int:
    """The estimate: ``COPIES`` x width x height x channels x 4 bytes."""
    return COPIES * int(width) * int(height) * int(channels) * 4


def check_frame(width: int, height: int, channels: int, what: str) -> None:
    """InputError when a ``width`` x ``height`` frame of ``channels`` float32 values per pixel
    cannot fit in the memory available now; ``what`` names the render ("the passes", ...)."""
    need = frame_bytes(width, height, channels)
    have = available_bytes()
    if have is None or need <= have:
        return
    gib = 1024.0**3
    raise InputError(
        f"{what} at {width}x{height}: about {need / gib:.1f} GiB of frame buffers ({channels} float32 values per"
        f" pixel, {COPIES} copies), more than the {have / gib:.1f} GiB of memory available; render at a smaller"
        " --resolution (or a lower Resolution % in the scene)"
    )
