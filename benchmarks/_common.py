"""What the benchmarks share: timing (fastest of several runs), their command-line options and
their results file."""

from __future__ import annotations

import json
import time

from sss_lab.core.base.files import write_text
from sss_lab.core.base.progress import saved_line


def fastest(fn, repeat: int, *, warm_up: bool = False) -> float:
    """Seconds of the fastest of ``repeat`` calls of ``fn`` (these machines are noisy: the
    fastest run is the one least disturbed); one untimed call first with ``warm_up``."""
    if warm_up:
        fn()
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def add_options(parser, *, repeat: int, results: str) -> None:
    parser.add_argument(
        "--repeat", type=int, default=repeat, help=f"runs per case, fastest reported (default: {repeat})"
    )
    parser.add_argument("--resolution", default="1920x1080", help="WxH (default: 1920x1080)")
    parser.add_argument("--out", default=results, help=f"JSON output (default: {results})")


def resolution(parser, text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        parser.error(f"--resolution: expected WxH such as 1920x1080, got {text!r}")
    if width < 1 or height < 1:
        parser.error(f"--resolution: expected a positive width and height, got {text!r}")
    return width, height


def write_results(path: str, data: dict) -> None:
    """Write the figures as JSON (atomically) and say where, as every command here does."""
    write_text(path, json.dumps(data, indent=2) + "\n")
    print(saved_line(path))
