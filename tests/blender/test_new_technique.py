"""The recipe of ``docs/adding-a-technique.md`` followed to the letter: its example technique is
built from the page's code blocks in a temporary package (outside the source tree), registered
with the registry line and the compositor's reason, and then every layer must pick it up with no
other edit: the command line (apply, ``--methods all``, ``--explain``, ``--param`` errors), plan and
apply, the fidelity table, compare's sweep and grid calibration, the panel's properties, and
``auto``, which must decline it cleanly. Its compiled kernel is compared with its NumPy reference
(check mode) on every call.

It runs in a fresh Python process: the panel's property groups and the command line's choices are
made from the registry when their modules are imported, as they are when the technique's one
registry line is added."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "adding-a-technique.md"
PACKAGE = "sss_recipe_example"


def recipe_files() -> dict[str, str]:
    """The page's code blocks marked ``<!-- file: NAME -->``, joined per file, with the package's
    relative imports of SSS Lab made absolute (the folder is outside core/techniques here)."""
    files: dict[str, str] = {}
    for name, code in re.findall(r"<!-- file: (\S+) -->\n```python\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S):
        files[name] = files[name] + "\n\n" + code if name in files else code
    for name, code in files.items():
        code = code.replace("from ...", "from sss_lab.core.").replace("from ..", "from sss_lab.core.techniques.")
        files[name] = code
    return files


SCRIPT = r"""
import contextlib, io, json, sys
import numpy as np

out = {}
from sss_recipe_example import blur as example
from sss_lab.core.techniques.registry import TECHNIQUES
TECHNIQUES.register(example.TECHNIQUE)  # the registry line
from sss_lab.nodes import setup
setup.NO_BUILDER["blur"] = "the recipe's example has no compositor group"  # the compositor's entry

from sss_lab.core.compute import backend
from sss_lab.core.scene.exr import Passes, read_layers
from sss_lab.core.study.synthetic import sphere_scene, write_scene
from sss_lab.addon import cli

arrays, scene = sphere_scene(48, 32)
exr = write_scene(sys.argv[1] + "/passes.exr", arrays, scene)

def run(*argv):
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        code = cli.main(list(argv))
    return code, buf.getvalue()

out["backend"] = backend.active()
out["apply"] = run("apply", exr, "--methods", "blur", "--param", "radius_px=3", "--out", sys.argv[1] + "/one.exr")
out["apply_layers"] = sorted(read_layers(sys.argv[1] + "/one.exr").layers)
out["all"] = run("apply", exr, "--methods", "all", "--out", sys.argv[1] + "/all.exr")
out["all_layers"] = sorted(read_layers(sys.argv[1] + "/all.exr").layers)
out["explain"] = run("apply", exr, "--methods", "blur", "--explain")
out["bad_param"] = run("apply", exr, "--methods", "blur", "--param", "radius_px=-3")
out["auto"] = run("apply", exr, "--methods", "auto", "--explain")

from sss_lab.core.study.fidelity import fidelity_table
material = max((m for m in scene.materials if m.scatters), key=lambda m: max(m.radius))
out["fidelity"] = sorted(fidelity_table(material, techniques=["blur", "burley"])["rows"])

from sss_lab.core.study import sweep
passes = Passes(arrays)
reference = np.array(passes["Combined"], dtype=np.float32)
mask = np.isin(np.rint(passes["Material Index"]).astype(int), [m.index for m in scene.materials if m.scatters])
spec = TECHNIQUES["blur"]
variants = [(spec.quality_label(q), dict(q)) for q in spec.qualities]
out["sweep"] = [r["mapping"] for r in sweep.sweep(passes, scene, reference, mask, 2, spec, "any", variants)]
grid = sweep.calibrate(passes, scene, reference, mask, box=2, techniques=[spec])
out["calibrate"] = [r["mapping"] for r in grid["rows"]]

import bpy
import sss_lab
sss_lab.register()
settings = bpy.context.scene.sss_lab
out["panel_items"] = [i.identifier for i in settings.bl_rna.properties["technique"].enum_items]
prop = settings.blur.bl_rna.properties["radius_px"]
out["panel_property"] = [settings.blur.radius_px, prop.hard_min, prop.hard_max, prop.description]
from sss_lab.addon.properties import technique_values
out["panel_values"] = technique_values(spec, settings.blur)
sss_lab.unregister()
print("RESULT " + json.dumps(out))
"""


def test_the_recipes_example_reaches_every_layer_without_another_edit(tmp_path):
    package = tmp_path / PACKAGE
    (package / "blur").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    files = recipe_files()
    assert sorted(files) == ["__init__.py", "_kernels.py", "technique.py"]
    for name, code in files.items():
        (package / "blur" / name).write_text(code)
    # sss_lab itself comes from where this process found it: the installed package or PYTHONPATH.
    path = os.pathsep.join(p for p in (str(tmp_path), os.environ.get("PYTHONPATH", "")) if p)
    env = dict(os.environ, SSS_LAB_BACKEND="check", PYTHONPATH=path)
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(tmp_path)], capture_output=True, text=True, env=env, cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    result = json.loads(next(line for line in proc.stdout.splitlines() if line.startswith("RESULT "))[7:])

    # Check mode (Numba is part of the set-up): each call compared the kernel with the NumPy reference.
    assert result["backend"] == "check"
    code, text = result["apply"]
    assert code == 0, text
    assert {"SSSLab.blur.Image", "SSSLab.blur.SSS"} <= set(result["apply_layers"])
    code, text = result["all"]
    assert code == 0, text
    layers = set(result["all_layers"])
    assert {"SSSLab.blur.Image", "SSSLab.burley.Image", "SSSLab.sta.Image"} <= layers
    code, text = result["explain"]
    assert code == 0 and "Blur (blur)" in text, text
    code, text = result["bad_param"]
    assert code != 0 and "blur.radius_px" in text and "-3" in text, text
    code, text = result["auto"]
    assert code == 0 and re.search(r"blur\s+not a candidate: its spec keeps it out of auto", text), text

    assert "Blur" in result["fidelity"] and "Burley" in result["fidelity"]
    assert result["sweep"] == ["Blur radius_px=1", "Blur radius_px=2", "Blur radius_px=4"]
    assert result["calibrate"] == ["radius_px=1", "radius_px=2", "radius_px=4", "radius_px=8"]

    assert "blur" in result["panel_items"]
    assert result["panel_property"] == [2, 0, 64, "Half-width of the square, pixels"]
    assert result["panel_values"] == {"radius_px": 2}
