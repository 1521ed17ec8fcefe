"""A Markdown table of linked scenes beside their typed-in twins, from fidelity runs (``run.py``
results), before and after a change::

    python -m benchmarks.fidelity.pairs --twins benchmarks.fidelity.textured \\
        --run before=out/fidelity_textured_before.json --run after=benchmarks/results/fidelity_textured.json

Per pair and run: each technique's share of the no-SSS error removed at its default quality
(``removed`` in the results) on the linked scene and on its twin, and the best of them. The
runs are labelled as given; the first run of the table is the one the others are read against.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys


def _removed(result: dict) -> dict[str, dict[str, float]]:
    """scene -> technique -> removed share at the default quality (no SSS left out)."""
    out: dict[str, dict[str, float]] = {}
    for scene in result["scenes"]:
        rows = [r for r in scene["rows"] if r.get("default") and r["technique"] != "none"]
        out[scene["scene"]] = {r["technique"]: float(r["removed"]) for r in rows}
    return out


def _pct(v: float | None) -> str:
    return "—" if v is None else f"{100 * v:+.0f}%"


def table(twins: dict[str, str], runs: list[tuple[str, dict]]) -> str:
    techniques = list(dict.fromkeys(t for _, r in runs for s in _removed(r).values() for t in s))
    lines = [
        "| scene (linked / typed in) | run | " + " | ".join(techniques) + " | best linked | best typed in |",
        "|---|---|" + "---|" * (len(techniques) + 2),
    ]
    for linked, typed in twins.items():
        for label, result in runs:
            removed = _removed(result)
            a, b = removed.get(linked, {}), removed.get(typed, {})
            cells = [f"{_pct(a.get(t))} / {_pct(b.get(t))}" for t in techniques]
            best_a = max(a.values(), default=None)
            best_b = max(b.values(), default=None)
            lines.append(
                f"| {linked} / {typed} | {label} | " + " | ".join(cells) + f" | {_pct(best_a)} | {_pct(best_b)} |"
            )
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--twins", required=True, help="a scenes module with a TWINS table (linked -> typed in)")
    parser.add_argument("--run", action="append", required=True, help="LABEL=results.json (repeatable)")
    args = parser.parse_args(argv)
    twins = importlib.import_module(args.twins).TWINS
    runs = []
    for item in args.run:
        label, sep, path = item.partition("=")
        if not sep:
            parser.error(f"--run: expected LABEL=PATH, got {item!r}")
        with open(path, encoding="utf-8") as f:
            runs.append((label, json.load(f)))
    print(table(twins, runs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
