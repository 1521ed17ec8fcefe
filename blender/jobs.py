"""Long jobs as generators: one unit of work (a frame, a Cycles render, a technique) per step.

A job's first ``yield`` comes after it has checked its input and planned, before it changes
anything, and says how many steps there are; each following ``yield`` comes after one unit of
work and announces the next (``Progress``). Its return value is the job's result. The plain
functions (``render_passes``, ``compare``; scripts and the command line) run their job to its
end with ``run``; the operators run one step per timer event (``operators/modal.py``), and
closing the generator between two steps (Esc) raises ``GeneratorExit`` at the ``yield``, which
unwinds the job's ``with SceneState()`` blocks: the scene is restored, while what the job
finished (frames written, references in the cache) stays.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from dataclasses import dataclass


@dataclass(frozen=True)
class Progress:
    """``done`` of ``total`` steps finished; ``message``: what the next step does; ``outputs``:
    the files the job has finished so far (they stay when it is cancelled)."""

    done: int
    total: int
    message: str = ""
    outputs: tuple[str, ...] = ()


Job = Generator[Progress, None, object]


class Steps:
    """The progress of a job whose step count is known when it starts: ``next(message)`` is
    yielded before each step and announces it."""

    def __init__(self, total: int):
        self.total = max(int(total), 1)
        self.done = -1

    def next(self, message: str, outputs: tuple[str, ...] = ()) -> Progress:
        self.done = min(self.done + 1, self.total - 1)
        return Progress(self.done, self.total, message, outputs)


def run(job: Job, progress: Callable[[Progress], None] | None = None):
    """Run ``job`` to its end; returns its result. ``progress`` gets every ``Progress``."""
    while True:
        try:
            step = next(job)
        except StopIteration as stop:
            return stop.value
        if progress is not None:
            progress(step)
