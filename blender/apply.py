"""Apply a technique to a passes EXR from inside Blender and load the result as an image.

``apply_passes(path, technique, ...)`` runs ``core.pipeline.sequence.apply_file`` (NumPy, the same code as
``python -m sss_lab apply``), which writes ``<stem>.sss.exr`` beside the passes, and loads the
result as a Blender image (a new data-block, or the same one reloaded when applied again).
"""

from __future__ import annotations

import os

import bpy

from ..core.pipeline.sequence import apply_file, default_output
from ..core.techniques.registry import check_technique


def load_result_image(path: str):
    """The image data-block of ``path``: loaded, or reloaded when it is already there."""
    path = os.path.abspath(path)
    for image in bpy.data.images:
        if image.filepath and os.path.abspath(bpy.path.abspath(image.filepath)) == path:
            image.reload()
            return image
    return bpy.data.images.load(path, check_existing=False)


def apply_passes(
    path: str,
    technique: str,
    *,
    out_path: str | None = None,
    albedo_mode: str = "post",
    overwrite: bool = True,
    load: bool = True,
    **options,
):
    """Apply ``technique`` to the passes file ``path``; returns (FileResult, image or None).

    ``out_path`` defaults to ``<stem>.sss.exr`` beside the input, which is never overwritten.
    Raises FileNotFoundError, ValueError or MissingPassError (a KeyError) with a clear message.
    """
    check_technique(technique)
    path = os.path.abspath(bpy.path.abspath(path)) if path else ""
    if not path:
        raise ValueError("no passes file: render the passes first (Render Passes) or choose an EXR")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such passes file (render the passes first, or choose an EXR)")
    result = apply_file(
        path,
        [technique],
        out_path=out_path or default_output(path),
        albedo_mode=albedo_mode,
        overwrite=overwrite,
        **options,
    )
    image = load_result_image(result.out_path) if (load and result.written) else None
    return result, image
