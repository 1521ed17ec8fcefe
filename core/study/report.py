"""The comparison report: metrics as JSON, a Markdown and an HTML page, pictures.

``write_report`` takes the measured data (plain dicts) and the linear images, and writes into
one folder:

- ``metrics.json``: everything measured; the pages are rendered from this same dict, so their
  numbers are the JSON's numbers;
- ``report.md`` and ``report.html`` (the HTML embeds the error-versus-time plot as SVG);
- ``images/*.png``: each image tone mapped, and its error map against the reference;
- ``grid.png``: no SSS / each technique / reference on the top rows, error heat maps below;
- ``pareto.svg``: relative RMSE against time, the Pareto front joined; ``pareto_samples.svg``: the
  same against samples per pixel, a cost that does not depend on the machine.

Nothing here renders or computes a technique: the caller (``blender/compare.py``) does.
"""

from __future__ import annotations

import html
import json
import math
import os
import re

import numpy as np

from ..base.files import write_text
from . import metrics as _metrics
from . import png

REPORT_VERSION = 1

METRIC_DEFINITIONS = {
    "rmse": "root mean square difference to the reference over the SSS pixels and RGB, linear radiance"
    " (after box x box mean downsampling of both images when box > 1)",
    "rel_rmse": "rmse divided by the mean reference value over the same pixels",
    "ssim": "mean SSIM (Wang et al. 2004, 7x7 Gaussian window) of tone-mapped luminance over the SSS pixels;"
    " 1 = identical",
    "time_s": "wall-clock seconds on this machine, end to end: for a technique, the passes render plus the"
    " apply; for Cycles, its render",
    "sss_effect_s": "what the SSS effect alone costs: a technique's apply; for Cycles at the passes' samples, its"
    " random-walk render minus the passes' render (Cycles without SSS at the same samples)",
    "bias": "the part of rel_rmse that stays with noise-free passes (the technique's own approximation plus the"
    " reference's noise), from the error with passes at two sample counts (pass noise variance falling as"
    " 1 / samples)",
    "pass_noise": "the part of rel_rmse that the passes' Monte Carlo noise adds: rel_rmse² = bias² + pass_noise²;"
    " for a denoised Cycles row, the noise the denoiser leaves, from a second seed (the rest, its bias, is what"
    " denoising changes)",
}


def pareto_cost(e: dict) -> float | None:
    """An entry's cost on the Pareto plot: what its SSS effect costs, a technique's own run (the
    median of its timed runs) where it is measured, else its whole render (a Cycles or EEVEE peer
    gives its subsurface scattering only with the render)."""
    t = e.get("time_s", {})
    return t.get("sss_effect") if t.get("sss_effect") is not None else t.get("total")


def samples_cost(e: dict) -> float | None:
    """An entry's cost on the samples axis: its samples per pixel (a technique's samples or taps
    and its per-light evaluations, a render's samples); None where it has none (no SSS)."""
    n = e.get("samples_per_pixel")
    return float(n) if n else None


def pareto_front(entries: list[dict], *, error_key: str = "rel_rmse", cost=pareto_cost) -> list[str]:
    """Names of the entries that no other entry beats on both cost (``cost``, by default
    ``pareto_cost``) and error."""
    pts = [
        (cost(e), e["metrics"][error_key], e["name"])
        for e in entries
        if e.get("metrics", {}).get(error_key) is not None and cost(e) is not None
    ]
    pts.sort()
    front, best = [], math.inf
    for _, err, name in pts:
        if err < best:
            front.append(name)
            best = err
    return front


def _fmt(value, digits: int = 4) -> str:
    if value is None:
        return "—"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


#: Label metrics for 12 px sans-serif text: average advance per character and line height (px).
_CHAR_W, _LINE_H = 7.0, 14.0


def _label_box(tx: float, ty: float, anchor: str, text: str) -> tuple[float, float, float, float]:
    w = _CHAR_W * len(text)
    x0 = tx - w if anchor == "end" else tx
    return (x0, ty - _LINE_H + 3, x0 + w, ty + 3)


def _overlaps(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def place_labels(points, texts, bounds) -> list[tuple[float, float, str, bool]]:
    """Positions for the labels of ``points`` so that no two labels overlap and none covers a
    point: (x, y, text-anchor, whether a leader line joins it to its point).

    Greedy, points in order: beside the point (right, or left in the plot's right third) just
    above or below it, then moved further up or down in steps of one line (with a leader line)
    until the label's box is free and inside ``bounds`` (x0, y0, x1, y1). A label that finds
    no free place keeps the nearest position inside the plot.
    """
    x_min, y_min, x_max, y_max = bounds
    placed: list[tuple[float, float, float, float]] = []
    dots = [(x - 4, y - 4, x + 4, y + 4) for x, y in points]
    out = []
    for (x, y), text in zip(points, texts, strict=True):
        right_third = x > x_min + (x_max - x_min) * 2 / 3
        sides = [("end", x - 6), ("start", x + 6)] if right_third else [("start", x + 6), ("end", x - 6)]
        choice = None
        for step in range(0, 40):
            for dy in (-6.0, 16.0) if step == 0 else (-6.0 - step * _LINE_H, 16.0 + step * _LINE_H):
                for anchor, tx in sides:
                    box = _label_box(tx, y + dy, anchor, text)
                    if box[0] < x_min or box[2] > x_max + 20 or box[1] < 0 or box[3] > y_max + 4:
                        continue
                    if any(_overlaps(box, b) for b in placed) or any(_overlaps(box, d) for d in dots):
                        continue
                    choice = (tx, y + dy, anchor, step > 0, box)
                    break
                if choice:
                    break
            if choice:
                break
        if choice is None:
            anchor, tx = sides[0]
            choice = (tx, min(max(y - 6.0, y_min + _LINE_H), y_max), anchor, False, _label_box(tx, y - 6, anchor, text))
        placed.append(choice[4])
        out.append(choice[:4])
    return out


#: The x axes of the two Pareto plots: (cost function, axis label, title).
PARETO_AXES = {
    "pareto.svg": (
        pareto_cost,
        "cost of the SSS effect, seconds (log): a technique's run, a peer's render",
        "Relative RMSE against the cost of the SSS effect; the Pareto front is joined",
    ),
    "pareto_samples.svg": (
        samples_cost,
        "samples per pixel (log): a technique's samples or taps (+1 per light it adds), a render's samples",
        "Relative RMSE against samples per pixel; the Pareto front is joined",
    ),
}


def pareto_svg(
    entries: list[dict], front: list[str], *, width: int = 640, height: int = 400, axis: str = "pareto.svg"
) -> str:
    """Relative RMSE (y) against a cost (x, log scale) as an SVG document: ``axis`` names one of
    ``PARETO_AXES`` (by default the SSS effect's seconds, ``pareto_cost``, a technique's drawn
    with the spread of its timed runs; or samples per pixel)."""
    pareto_cost, x_label, title = PARETO_AXES[axis]
    pts = [e for e in entries if e["metrics"].get("rel_rmse") is not None and pareto_cost(e)]
    left, right, top, bottom = 70, 20, 20, 50
    if not pts:
        return f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}"></svg>'
    times = [max(float(pareto_cost(e) or 0.0), 1e-6) for e in pts]
    errs = [e["metrics"]["rel_rmse"] for e in pts]
    lx0, lx1 = math.log10(min(times)) - 0.1, math.log10(max(times)) + 0.1
    y1 = max(errs) * 1.1 or 1.0

    def sx(t):
        return left + (math.log10(max(t, 1e-6)) - lx0) / (lx1 - lx0) * (width - left - right)

    def sy(v):
        return height - bottom - v / y1 * (height - top - bottom)

    colours = {"technique": "#1f77b4", "cycles": "#d62728", "baseline": "#7f7f7f", "eevee": "#ff7f0e"}
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}"'
        ' font-family="sans-serif" font-size="12" role="img">',
        f"<title>{title}</title>",
        f'<rect x="0" y="0" width="{width}" height="{height}" fill="white"/>',
        f'<line x1="{left}" y1="{height - bottom}" x2="{width - right}" y2="{height - bottom}" stroke="black"/>',
        f'<line x1="{left}" y1="{top}" x2="{left}" y2="{height - bottom}" stroke="black"/>',
        f'<text x="{(left + width - right) / 2}" y="{height - 12}" text-anchor="middle">{html.escape(x_label)}</text>',
        f'<text x="14" y="{(top + height - bottom) / 2}" text-anchor="middle" '
        f'transform="rotate(-90 14 {(top + height - bottom) / 2})">relative RMSE</text>',
    ]
    for k in range(math.floor(lx0), math.ceil(lx1) + 1):
        for m in (1, 2, 5):
            t = m * 10.0**k
            if lx0 <= math.log10(t) <= lx1:
                x = sx(t)
                out.append(
                    f'<line x1="{x:.1f}" y1="{height - bottom}" x2="{x:.1f}" y2="{height - bottom + 4}" '
                    'stroke="black"/>'
                )
                out.append(f'<text x="{x:.1f}" y="{height - bottom + 16}" text-anchor="middle">{t:g}</text>')
    for i in range(5):
        v = y1 * i / 4
        out.append(f'<text x="{left - 6}" y="{sy(v) + 4:.1f}" text-anchor="end">{v:.3g}</text>')
        out.append(f'<line x1="{left}" y1="{sy(v):.1f}" x2="{width - right}" y2="{sy(v):.1f}" stroke="#eee"/>')
    by_name = {e["name"]: e for e in pts}
    chain = [by_name[n] for n in front if n in by_name]
    if len(chain) > 1:
        path = " ".join(f"{sx(pareto_cost(e)):.1f},{sy(e['metrics']['rel_rmse']):.1f}" for e in chain)
        out.append(f'<polyline points="{path}" fill="none" stroke="#2ca02c" stroke-width="1.5"/>')
    xy = [(sx(pareto_cost(e)), sy(e["metrics"]["rel_rmse"])) for e in pts]
    for e, (_, y) in zip(pts, xy, strict=True):  # the spread of a technique's timed runs
        spread = e["time_s"].get("sss_effect_spread") if axis == "pareto.svg" else None
        if spread and spread[1] > spread[0] > 0:
            out.append(
                f'<line x1="{sx(spread[0]):.1f}" y1="{y:.1f}" x2="{sx(spread[1]):.1f}" y2="{y:.1f}" stroke="#1f77b4"'
                ' stroke-width="1"/>'
            )
    labels = place_labels(xy, [e["name"] for e in pts], (left, top, width - right, height - bottom))
    for e, (x, y), (tx, ty, anchor, leader) in zip(pts, xy, labels, strict=True):
        colour = colours.get(str(e.get("kind")), "black")
        out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{colour}"/>')
        if leader:
            out.append(
                f'<line x1="{x:.1f}" y1="{y:.1f}" x2="{tx:.1f}" y2="{ty - 4:.1f}" stroke="#999" stroke-width="0.8"/>'
            )
        out.append(f'<text x="{tx:.1f}" y="{ty:.1f}" text-anchor="{anchor}">{html.escape(e["name"])}</text>')
    out.append("</svg>")
    return "\n".join(out)


def _per_material(entries: list[dict]) -> list[str]:
    """The error table per subsurface material (entries' ``by_material``; nothing when the scene
    has one material, whose figures are the table above)."""
    names = list(dict.fromkeys(n for e in entries for n in e.get("by_material", {})))
    if not names:
        return []
    lines = [
        "",
        "## Per material",
        "",
        "Relative RMSE over each subsurface material's pixels alone (the table above: over all of them).",
        "",
        "| image | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for e in entries:
        by = e.get("by_material", {})
        lines.append(f"| {e['name']} | " + " | ".join(_fmt(by.get(n, {}).get("rel_rmse")) for n in names) + " |")
    return lines


def _materials_read(data: dict) -> list[str]:
    """What the scene reader and the passes said about each subsurface material (its notes: where
    its Principled BSDF was found, each input read per pixel or at a stand-in value); nothing when
    every input was typed in."""
    materials = [m for m in data.get("scene", {}).get("materials", []) if m.get("notes")]
    if not materials:
        return []
    lines = ["", "## Materials as read", ""]
    for m in materials:
        lines.append(f"- **{m.get('name', '?')}**: " + "; ".join(str(n) for n in m["notes"]) + ".")
    return lines


#: The verdict's error target: the cheapest technique within this share of the best one's error
#: (``apply --methods auto``'s default margin, ``core.pipeline.auto.DEFAULT_MAX_ERROR``; a test
#: keeps the two equal).
VERDICT_MARGIN = 0.03


def verdict(data: dict, margin: float = VERDICT_MARGIN) -> list[dict]:
    """Per material (the whole of the subsurface pixels when there is one): the technique to use,
    the cheapest whose error is within ``margin`` of the best technique's; what it removes of the
    no-SSS error and what its SSS effect costs; the next cheaper and the next better technique;
    whether its error is inside the reference's noise floor (cannot be told from it); and the peer
    (a Cycles or EEVEE row) with the lowest error, with its end-to-end time."""
    entries = data.get("entries", [])
    techniques = [e for e in entries if e.get("kind") == "technique"]
    none = next((e for e in entries if e.get("kind") == "baseline"), None)
    if not techniques:
        return []
    scopes: list[str | None] = list(sorted(techniques[0].get("by_material") or {})) or [None]
    floor = (data.get("noise_floor") or {}).get("rel_rmse")
    out = []
    for scope in scopes:
        errors = {e["name"]: _scope_error(e, scope) for e in entries}
        base = errors.get(none["name"]) if none is not None else None
        # name -> (error, cost) of every technique row measured on this scope.
        rows: dict[str, tuple[float, float]] = {}
        for e in techniques:
            err, cost = errors[e["name"]], pareto_cost(e)
            if err is not None and cost is not None:
                rows[e["name"]] = (err, cost)
        if not rows:
            continue
        best = min(err for err, _ in rows.values())
        use = min((n for n, (err, _) in rows.items() if err <= best * (1 + margin)), key=lambda n: rows[n][::-1])
        err_use, cost_use = rows[use]

        def described(name: str | None, cost: float | None = None, base=base, errors=errors, rows=rows) -> dict | None:
            if name is None:
                return None
            err = errors[name]
            return {
                "name": name,
                "rel_rmse": err,
                "removed": None if not base or err is None else 1.0 - err / base,
                "cost_s": rows[name][1] if cost is None else cost,
            }

        cheaper = [n for n, (_, c) in rows.items() if c < cost_use]
        better = [n for n, (err, _) in rows.items() if err < err_use]
        peers: dict[str, tuple[float, float, str]] = {}
        for e in entries:
            err = errors[e["name"]]
            if e.get("kind") in ("cycles", "eevee") and err is not None:
                peers[e["name"]] = (err, float((e.get("time_s") or {}).get("total") or 0.0), str(e.get("kind")))
        peer = min(peers, key=lambda n: peers[n][0]) if peers else None
        out.append(
            {
                "material": scope or "every subsurface material",
                "use": described(use),
                "margin": margin,
                "within_noise_floor": floor is not None and err_use <= floor,
                "next_cheaper": described(min(cheaper, key=lambda n: rows[n][0]) if cheaper else None),
                "next_better": described(min(better, key=lambda n: rows[n][::-1]) if better else None),
                "peer": None if peer is None else {**(described(peer, peers[peer][1]) or {}), "kind": peers[peer][2]},
            }
        )
    return out


def _scope_error(e: dict, scope: str | None) -> float | None:
    """A row's rel_rmse over the subsurface pixels (``scope`` None) or one material's."""
    m = (e.get("by_material") or {}).get(scope) if scope is not None else e.get("metrics")
    value = None if m is None else m.get("rel_rmse")
    return None if value is None else float(value)


def _verdict_lines(data: dict) -> list[str]:
    items = data.get("verdict") or []
    if not items:
        return []

    def pct(v):
        return "n/a" if v is None else f"{100 * v:.0f} %"

    def ms(v):
        return "n/a" if v is None else (f"{1000 * v:.0f} ms" if v < 1 else f"{v:.2f} s")

    lines = [
        "## Verdict",
        "",
        f"Per material, the cheapest technique whose error is within {100 * VERDICT_MARGIN:.0f} % of the best"
        " technique's (what `apply --methods auto` keeps), what it removes of the no-SSS error and what its SSS"
        " effect costs:",
        "",
    ]
    for v in items:
        u = v["use"]
        text = (
            f"- **{v['material']}: use {u['name']}**: removes {pct(u['removed'])} of the no-SSS error"
            f" (rel. RMSE {_fmt(u['rel_rmse'])}), its SSS effect {ms(u['cost_s'])}."
        )
        if v["within_noise_floor"]:
            text += " Inside the noise floor: the reference's own noise is as large."
        if v["next_cheaper"]:
            c = v["next_cheaper"]
            text += f" Cheaper: {c['name']} removes {pct(c['removed'])} in {ms(c['cost_s'])}."
        if v["next_better"]:
            b = v["next_better"]
            text += f" Better: {b['name']} removes {pct(b['removed'])} in {ms(b['cost_s'])}."
        if v["peer"]:
            p = v["peer"]
            text += f" Best peer: {p['name']} removes {pct(p['removed'])}, {ms(p['cost_s'])} end to end."
        lines.append(text)
    return lines + [""]


def _markdown(data: dict) -> str:
    s = data.get("settings", {})
    lines = [
        f"# SSS Lab comparison: {data.get('scene', {}).get('name', '')}",
        "",
        "Each technique's image against Cycles' random-walk reference, over the pixels of the subsurface materials.",
        "",
    ]
    if not data.get("complete", False):
        lines += ["**This report is incomplete:** " + "; ".join(data.get("notes", [])), ""]
    lines += _verdict_lines(data)
    lines += [
        f"- Reference: Cycles {s.get('reference_method', 'RANDOM_WALK')}, {s.get('reference_samples')} samples,"
        + (
            f" merged from {len(s['reference_seeds'])} seeds"
            if len(s.get("reference_seeds") or []) > 1
            else f" seed {s.get('seed')}"
        )
        + f", adaptive sampling off; resolution {s.get('resolution')}.",
        f"- Passes for the techniques: {s.get('pass_samples')} samples, subsurface weight 0"
        + (
            f"; again at {s['bias_pass_samples']} samples to split the error into bias and pass noise."
            if s.get("bias_pass_samples")
            else "."
        ),
        f"- Metric box downsampling: {s.get('box')} x {s.get('box')}.",
    ]
    nf = data.get("noise_floor")
    if nf and nf.get("halves"):
        halves = nf["halves"]["samples"]
        lines.append(
            f"- Reference seeds: {', '.join(map(str, s.get('reference_seeds') or []))}."
            f" Noise floor from the reference's two halves ({halves[0]} + {halves[1]} samples, RMSE scaled by"
            f" {_fmt(nf.get('scale'))} to a second seed's): rel. RMSE {_fmt(nf.get('rel_rmse'))}."
            " Differences below it are not meaningful."
        )
    elif nf:
        lines.append(
            f"- Noise floor (reference against a second seed): rel. RMSE {_fmt(nf.get('rel_rmse'))},"
            f" SSIM {_fmt(nf.get('ssim'))}. Differences below it are not meaningful."
        )
    lines += [
        "",
        "## Error and time",
        "",
        "Error: relative RMSE, split into bias (stays with noise-free passes) and pass noise (what the passes'"
        " noise adds). Time: end to end, and the SSS effect alone (see the costs below).",
        "",
        "| image | kind | rel. RMSE | bias | pass noise | RMSE | SSIM | end to end s | SSS effect s | Pareto |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    front = set(data.get("pareto", []))
    floor = (data.get("noise_floor") or {}).get("rel_rmse")
    for e in data.get("entries", []):
        m, t = e["metrics"], e["time_s"]
        inside = floor is not None and m.get("rel_rmse") is not None and m["rel_rmse"] <= floor
        mark = "; ".join(
            x for x in ("yes" if e["name"] in front else "", "inside the noise floor" if inside else "") if x
        )
        lines.append(
            f"| {e['name']} | {e['kind']} | {_fmt(m.get('rel_rmse'))} | {_fmt(m.get('bias'))} |"
            f" {_fmt(m.get('pass_noise'))} | {_fmt(m.get('rmse'))} | {_fmt(m.get('ssim'))}"
            f" | {_fmt(t.get('total'), 3)} | {_fmt(t.get('sss_effect'), 3)} | {mark} |"
        )
    lines += _per_material(data.get("entries", []))
    lines += _materials_read(data)
    costs = data.get("costs")
    if costs:
        lines += [
            "",
            "## Two costs",
            "",
            costs["definition"],
            "",
            f"- Cycles random walk, {costs['samples']} samples: {_fmt(costs['cycles_random_walk_s'], 3)} s; without"
            f" SSS (the passes): {_fmt(costs['cycles_without_sss_s'], 3)} s; the SSS effect alone:"
            f" {_fmt(costs['cycles_sss_effect_s'], 3)} s.",
            "",
            "| technique | SSS effect alone s | end to end s |",
            "|---|---|---|",
        ]
        for row in costs["techniques"]:
            lines.append(f"| {row['name']} | {_fmt(row['sss_effect_s'], 3)} | {_fmt(row['end_to_end_s'], 3)} |")
    lines += [
        "",
        "![error against time](pareto.svg)",
        "",
        "![error against samples per pixel](pareto_samples.svg)",
        "",
        "![images](grid.png)",
        "",
    ]
    if data.get("summary"):
        lines += ["![summary](summary.png)", ""]
    grid = data.get("grid")
    if grid:
        white = _fmt(grid["error_scale_white"], 3)
        lines += [
            "Columns, left to right: " + ", ".join(grid["columns"]) + ". Top row: tone-mapped image; bottom row:"
            f" relative luminance error against the reference (black 0, white at {white}).",
            "",
        ]
    pictures = [e for e in data.get("entries", []) if e.get("image")]
    if pictures:
        lines += ["## Images", "", "| image | picture | error map |", "|---|---|---|"]
        for e in pictures:
            err = f"![error of {e['name']}]({e['error_image']})" if e.get("error_image") else ""
            lines.append(f"| {e['name']} | ![{e['name']}]({e['image']}) | {err} |")
        ref_image = data.get("reference_image")
        if ref_image:
            lines.append(f"| reference | ![reference]({ref_image}) | |")
        lines.append("")
    fid = data.get("fidelity")
    if fid:
        lines += [
            "## Visual fidelity, measured",
            "",
            fid.get("definition", ""),
            "",
            "| technique | non-local diffusion: 90 % radius (R / G / B), scene units | colour bleeding:"
            " R/B spread ratio | energy out / in (R / G / B) |",
            "|---|---|---|---|",
        ]
        for name, row in fid.get("rows", {}).items():
            r90 = " / ".join(_fmt(v, 3) for v in row["r90_su"])
            energy = " / ".join(_fmt(v, 4) for v in row["energy_ratio"])
            lines.append(f"| {name} | {r90} | {_fmt(row['bleeding_ratio'], 3)} | {energy} |")
        lines.append("")
    cal = data.get("calibration")
    if cal:
        lines += [
            "## Material mapping calibration",
            "",
            cal.get("definition", ""),
            "",
            "| method | technique | mapping | rel. RMSE | chosen |",
            "|---|---|---|---|---|",
        ]
        for row in cal.get("rows", []):
            lines.append(
                f"| {row['method']} | {row['technique']} | {row['mapping']} | {_fmt(row.get('rel_rmse'))} |"
                f" {'yes' if row.get('chosen') else ''} |"
            )
        lines.append("")
    lines += ["## Definitions", ""] + [f"- **{k}**: {v}" for k, v in METRIC_DEFINITIONS.items()] + [""]
    return "\n".join(lines)


_MD_IMAGE = re.compile(r"!\[([^\]]*)\]\(([^)]+)\)")
_MD_BOLD = re.compile(r"\*\*(.+?)\*\*")


def _html_text(text: str) -> str:
    """Escaped text, with Markdown's **bold** as <strong>."""
    return _MD_BOLD.sub(r"<strong>\1</strong>", html.escape(text))


def _html_cell(text: str, tag: str = "td") -> str:
    """A table cell: Markdown images become <img>, everything else is escaped text."""
    m = _MD_IMAGE.fullmatch(text)
    if m:
        alt, src = (html.escape(g, quote=True) for g in m.groups())
        return f'<{tag}><a href="{src}"><img src="{src}" alt="{alt}" width="128"></a></{tag}>'
    return f"<{tag}>{html.escape(text)}</{tag}>"


#: The page's style. Wide content (tables, the plot, the grid) scrolls inside its own box, so
#: the page itself never scrolls sideways on a phone and the text keeps its size.
_STYLE = (
    "body{font-family:sans-serif;font-size:16px;line-height:1.4;max-width:1100px;margin:0 auto;padding:0 12px 2em}"
    "h1{font-size:1.5em}h2{font-size:1.25em;margin-top:1.5em}p,li{overflow-wrap:anywhere}"
    ".wide{overflow-x:auto;margin:1em 0}table{border-collapse:collapse}"
    "td,th{border:1px solid #ccc;padding:2px 8px;text-align:right;vertical-align:top}"
    "th{background:#f4f4f4}td:first-child,th:first-child{text-align:left}"
    "img{image-rendering:pixelated}.wide>svg{display:block}"
    ".stage{position:relative;display:inline-block;cursor:zoom-in}.stage img{display:block;width:256px}"
    ".stage img.over{position:absolute;left:0;top:0}.stage.zoomed{cursor:zoom-out}.stage.zoomed img{width:1024px}"
)


#: The before/after viewer: one image over the reference, a slider that shows more of one or the
#: other, and a click that zooms (pixelated) or zooms back out. Plain JavaScript, no dependency.
_VIEWER_SCRIPT = """
(function () {
  const v = document.getElementById('viewer'); if (!v) return;
  const pick = v.querySelector('select'), slider = v.querySelector('input[type=range]');
  const top = v.querySelector('img.over'), stage = v.querySelector('.stage');
  function show() {
    top.src = pick.value;
    top.style.clipPath = 'inset(0 ' + (100 - slider.value) + '% 0 0)';
  }
  pick.addEventListener('change', show); slider.addEventListener('input', show);
  stage.addEventListener('click', function () { stage.classList.toggle('zoomed'); });
  show();
})();
"""


def _viewer(data: dict) -> str:
    """The viewer's HTML (``_VIEWER_SCRIPT``): the entries with a picture against the reference."""
    ref = data.get("reference_image")
    pictures = [e for e in data.get("entries", []) if e.get("image")]
    if not ref or not pictures:
        return ""
    options = "".join(
        f'<option value="{html.escape(e["image"], quote=True)}">{html.escape(e["name"])}</option>' for e in pictures
    )
    src = html.escape(ref, quote=True)
    return (
        "<h2>Before and after</h2><p>Pick an image: left of the slider it, right of it the reference. Click to zoom."
        f'</p><div id="viewer"><p><select aria-label="image">{options}</select> '
        '<input type="range" min="0" max="100" value="50" aria-label="split"></p>'
        f'<div class="wide"><div class="stage"><img class="under" src="{src}" alt="reference">'
        f'<img class="over" src="{html.escape(pictures[0]["image"], quote=True)}" alt="compared"></div></div></div>'
        f"<script>{_VIEWER_SCRIPT}</script>"
    )


def _html(data: dict, svgs: dict[str, str]) -> str:
    # The Markdown is the single source of the text; the HTML shows it as tables plus the pictures.
    lines = _markdown(data).splitlines()
    body: list[str] = []
    block = ""  # the open element that groups lines: "table", "ul" or ""

    def open_block(kind: str) -> None:
        nonlocal block
        if block == kind:
            return
        if block:
            body.append("</table></div>" if block == "table" else "</ul>")
        if kind:
            body.append('<div class="wide"><table>' if kind == "table" else "<ul>")
        block = kind

    for k, line in enumerate(lines):
        if line.startswith("|---"):
            continue
        if line.startswith("| "):
            open_block("table")
            header = k + 1 < len(lines) and lines[k + 1].startswith("|---")
            cells = [c.strip() for c in line.strip("|").split("|")]
            body.append("<tr>" + "".join(_html_cell(c, "th" if header else "td") for c in cells) + "</tr>")
            continue
        if line.startswith("- "):
            open_block("ul")
            body.append(f"<li>{_html_text(line[2:])}</li>")
            continue
        open_block("")
        if line.startswith("# "):
            body.append(f"<h1>{html.escape(line[2:])}</h1>")
        elif line.startswith("## "):
            body.append(f"<h2>{html.escape(line[3:])}</h2>")
        elif line.startswith("![error"):
            body.append(f'<div class="wide">{svgs[line[line.rindex("(") + 1 : -1]]}</div>')
        elif line.startswith("![images]"):
            body.append('<div class="wide"><a href="grid.png"><img src="grid.png" alt="images"></a></div>')
            body.append(_viewer(data))
        elif line.startswith("![summary]"):
            body.append('<div class="wide"><a href="summary.png"><img src="summary.png" alt="summary"></a></div>')
        elif line.strip():
            body.append(f"<p>{_html_text(line)}</p>")
    open_block("")
    title = html.escape(f"SSS Lab report: {data.get('scene', {}).get('name', '')}")
    return (
        "<!doctype html><html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        f"<title>{title}</title><style>{_STYLE}</style></head><body>{''.join(body)}</body></html>\n"
    )


def write_report(
    out_dir: str,
    data: dict,
    images: dict[str, np.ndarray],
    *,
    reference: str,
    mask: np.ndarray | None = None,
    order: list[str] | None = None,
    summary: list[str] | None = None,
    exposure: float = 1.0,
) -> dict:
    """Write the report folder; returns ``data`` completed with ``pareto`` and image paths.

    ``images`` maps entry names (and the reference's name ``reference``) to linear RGB(A)
    arrays of one size. Error maps are relative luminance error against the reference, the
    heat ramp's white at ``2 x`` the largest median error.
    """
    if reference not in images:
        raise ValueError(f"reference image {reference!r} is not among the images: {sorted(images)}")
    data = dict(data)
    data["version"] = REPORT_VERSION
    data["metric_definitions"] = METRIC_DEFINITIONS
    data["pareto"] = pareto_front(data.get("entries", []))
    data["pareto_samples"] = pareto_front(data.get("entries", []), cost=samples_cost)
    data["verdict"] = verdict(data)
    img_dir = os.path.join(out_dir, "images")
    ref = images[reference]
    names = order or list(images)
    err_maps = {n: _metrics.error_map(images[n], ref) for n in names if n != reference}
    vmax = 2.0 * max(
        [
            float(np.median(e[mask])) if mask is not None and mask.any() else float(np.median(e))
            for e in err_maps.values()
        ]
        + [1e-3]
    )
    tops, bottoms = [], []
    for n in names:
        slug = "".join(c if c.isalnum() else "_" for c in n).strip("_")
        disp = png.to_display(images[n], exposure=exposure)
        png.write_png(os.path.join(img_dir, f"{slug}.png"), disp)
        tops.append(disp)
        if n in err_maps:
            heat = png.heat(err_maps[n], vmax=vmax)
            png.write_png(os.path.join(img_dir, f"{slug}_error.png"), heat)
            bottoms.append(heat)
        else:
            bottoms.append(np.zeros_like(disp))
        if n == reference:
            data["reference_image"] = f"images/{slug}.png"
        for e in data.get("entries", []):
            if e["name"] == n:
                e["image"] = f"images/{slug}.png"
                if n in err_maps:
                    e["error_image"] = f"images/{slug}_error.png"
    png.write_png(os.path.join(out_dir, "grid.png"), png.grid(tops + bottoms, columns=len(names)))
    picked = [n for n in (summary or []) if n in images]
    if picked:
        # A short grid for a first look: the same tiles, fewer columns (README figures use it).
        index = {n: i for i, n in enumerate(names)}
        tiles = [tops[index[n]] for n in picked] + [bottoms[index[n]] for n in picked]
        png.write_png(os.path.join(out_dir, "summary.png"), png.grid(tiles, columns=len(picked)))
        data["summary"] = {"file": "summary.png", "columns": picked}
    data["grid"] = {
        "file": "grid.png",
        "columns": names,
        "error_scale_white": vmax,
        "rows": ["tone-mapped image", "relative luminance error (black 0, white at error_scale_white)"],
    }
    svgs = {
        "pareto.svg": pareto_svg(data.get("entries", []), data["pareto"]),
        "pareto_samples.svg": pareto_svg(data.get("entries", []), data["pareto_samples"], axis="pareto_samples.svg"),
    }
    for name, svg in svgs.items():
        write_text(os.path.join(out_dir, name), svg)
    write_text(os.path.join(out_dir, "metrics.json"), json.dumps(data, indent=2, sort_keys=True))
    write_text(os.path.join(out_dir, "report.md"), _markdown(data))
    write_text(os.path.join(out_dir, "report.html"), _html(data, svgs))
    return data


def report_files(out_dir: str, data: dict) -> list[str]:
    """Every file ``write_report`` wrote for ``data`` (its return value), images first."""
    images = [data.get("reference_image")]
    for e in data.get("entries", []):
        images += [e.get("image"), e.get("error_image")]
    names = [n for n in dict.fromkeys(images) if n]
    names += ["grid.png"] + (["summary.png"] if data.get("summary") else [])
    names += [*PARETO_AXES, "metrics.json", "report.md", "report.html"]
    return [os.path.join(out_dir, n) for n in names]
