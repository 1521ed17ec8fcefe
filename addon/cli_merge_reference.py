"""``python -m sss_lab merge-reference DIR --out reference.exr``: merge the reference's parts.

Reads the parts ``reference`` wrote (the files, or the folders holding them), checks that they
render the same scene, frame and size with different seeds, and writes their sample-weighted
mean: one reference of the summed samples, with the two halves of the parts as extra layers for
the noise floor (``compare --reference`` reads them over the subsurface pixels). Needs only NumPy
and OpenEXR. Prints the noise floor over the whole image and ``Saved: '<path>'`` per file.
"""

from __future__ import annotations

import glob
import os


def add_parser(subparsers):
    p = subparsers.add_parser(
        "merge-reference",
        help="merge reference parts rendered with different seeds into one (NumPy and OpenEXR only)",
        description=__doc__.split("\n\n", 1)[1],
    )
    p.add_argument("parts", nargs="+", help="part EXR files, or folders of reference_seed_*.exr")
    p.add_argument("--out", required=True, help="the merged reference EXR (a .json is written beside it)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing merged reference")
    p.set_defaults(run=run)


def _part_files(items: list[str]) -> list[str]:
    from ..core.study.reference import PART_PATTERN

    pattern = PART_PATTERN.split("{", 1)[0] + "*.exr"
    files = []
    for item in items:
        if os.path.isdir(item):
            found = sorted(glob.glob(os.path.join(glob.escape(item), pattern)))
            if not found:
                raise FileNotFoundError(f"{item}: no {pattern} in this folder (render them with sss_lab reference)")
            files += found
        else:
            files.append(item)
    return list(dict.fromkeys(os.path.abspath(f) for f in files))


def run(args) -> int:
    from ..core.base.progress import printable, saved_line
    from ..core.study import reference
    from .cli import CommandError

    files = _part_files(args.parts)
    out = os.path.abspath(args.out)
    if os.path.isdir(out):
        raise CommandError(f"--out {printable(args.out)!r} is a folder; expected the merged reference's EXR file name")
    # Every file the merge writes against every file it reads, links resolved: a folder reached
    # through a link, or an output whose JSON is a part's, must not replace an input.
    inputs = {os.path.realpath(f) for f in files} | {os.path.realpath(reference.sidecar(f)) for f in files}
    for what, path in (("--out", out), ("the JSON beside --out", reference.sidecar(out))):
        if os.path.realpath(path) in inputs:
            raise CommandError(
                f"{what} {printable(path)!r} is one of the parts or a part's JSON; refusing to overwrite it"
                " (choose another output name)"
            )
    parts, metas = reference.read_parts(files)
    merged = reference.merge_parts(parts)
    counts = sorted({p.samples for p in parts})
    print(
        f"merge-reference: {len(parts)} part(s), seeds {', '.join(map(str, merged.seeds))}, "
        f"{'/'.join(map(str, counts))} samples each: {merged.samples} samples"
    )
    floor = reference.noise_floor(merged)
    if floor is None or merged.half_samples is None:
        print("merge-reference: one part only: no noise floor (it needs two halves)")
    else:
        print(
            f"merge-reference: noise floor from the halves ({merged.half_samples[0]} + {merged.half_samples[1]} "
            f"samples), whole image: rel. RMSE {floor['rel_rmse']:.4f}"
        )
    keep = ("fingerprint", "frame", "resolution", "scene", "blender")
    meta = {k: metas[0].get(k) for k in keep if k in metas[0]}
    meta["parts"] = [os.path.basename(f) for f in files]
    meta["seconds"] = sum(float(m.get("seconds") or 0.0) for m in metas)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    for path in reference.write_merged(out, merged, meta, overwrite=args.overwrite):
        print(saved_line(path), flush=True)
    return 0
