"""Command-line fault cases, run as a user or a render farm runs them: ``python -m benchmarks.reliability_cli``.

``benchmarks/reliability.py`` feeds generated damage to the code in-process; the cases here go
through the command line instead. Each case builds its inputs in a folder of its own, runs
``python -m sss_lab COMMAND ...`` in a subprocess (two at once for the concurrency cases, under a
signal for the interrupt cases, with a small tmpfs mounted in a private mount namespace for a
full or read-only disk) and judges only what happens: the exit status, what stdout and stderr
say, the files on disk and the hashes of the inputs before and after. Nothing is judged from
reading the code. A case is

- **handled** when the command gives one clear error naming the problem with the documented exit
  status (2 bad input, 1 a failed write, 130 interrupted), without a traceback, with its inputs
  unchanged and no partial or temporary file left; or a complete, finite result (with the note
  the case asks for, where a silent result would be wrong);
- **not handled** otherwise, with the reason observed;
- **not run here** when this machine lacks what the case needs (a mount namespace for the small
  disks), with the reason.

The classes (their short ids are what ``--only`` takes):

- SEC: security of names and scripts: scripts inside a .blend while Blender's preferences allow
  them to run (the command called in a process whose preferences say so, as ``blender -y`` or a
  user's "Auto Run Python Scripts" would), and names holding a newline, a forged ``Saved:`` line
  or terminal escapes.
- EXR: passes files that are not plain scanline EXR images on disk (a deep image, a named pipe,
  a device), and a Material Index between two materials.
- JSON: scene descriptions with absurd content: 100000 nested arrays, a Subsurface Weight of 2,
  the Depth pass named as the thickness map.
- OUT: outputs over inputs and failed writes: ``--json`` naming the input or ``--out``, images
  over files the bake did not make, a merged reference written through a linked folder or over a
  part's JSON, ``--out`` a folder, a full or read-only disk.
- CONC: two runs started together writing one output.
- MERGE: merged references and their parts: parts without a scene fingerprint, a merged
  reference's JSON cut short, of the wrong type or with text for numbers, a passes file given as
  a reference.
- RESUME: ``--skip-existing`` over a cut-short output, or a frame of another size or scene.
- BLEND: what the scene reader must see or name: a Principled BSDF in a node group or on an
  inactive Material Output, textured inputs, materials set by Geometry Nodes, a driven Weight,
  a render border, two meshes whose names clean alike.
- CLI: flags misused: given twice, empty, a huge resolution, a file for a folder, and messages
  that must name the flag typed rather than a settings field.
- INT: interrupts and signals: Ctrl-C, SIGTERM and SIGHUP during render, calibrate, reference,
  compare and the kernel compilation.
- EXRV: pass values near float32's largest value, a pass with a channel too many.
- MAT: a Subsurface Radius or Scale of zero: the message must name it.
- UNIT: the same scene 1000 times larger or smaller (its passes and description with every
  length scaled, so that no render noise comes between the two): the SSS term must not change.
- SCENE: a compare whose subsurface materials are all off screen.
- CLI4: ``all`` combined with another technique, ``--frames ''``.
- CACHE: the compare's reference cache and a merged reference with damaged or absurd metadata
  or pixels.
- VERIFY: the .blend writes of bake-thickness and calibrate on a fit that succeeds: ``--json``
  over the input or the output, two runs at once, a full disk.
- KILL: a command killed with SIGKILL (nothing can be cleaned up then), and the same command run
  again.

Run from the project root with the project's environment (bpy is needed for the fixtures)::

    .venv/bin/python -m benchmarks.reliability_cli --table
    .venv/bin/python -m benchmarks.reliability_cli --only RESUME,CACHE --json cases.json
    .venv/bin/python -m benchmarks.reliability_cli --ids re01_render_skip_truncated --keep

Renders are 48x48 (32x32 and 64x64 where a case needs it) at a few samples, and the interrupt
cases stop their long renders within seconds: the whole run takes about 4 minutes on 2 cores.
It is run by hand, not by CI. The fixtures (the sample scenes ``head_frontlit`` and
``backlit_thin``, their passes, a reference in parts and merged, the compare's cache, and
.blend files built with bpy to hold scripts, hostile names and the scene constructs above) are
made once per run in one temporary work folder, removed at the end unless ``--keep``.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import os
import re
import resource
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PYTHON = sys.executable
HANDLED, NOT_HANDLED, NOT_RUN = "handled", "not handled", "not run here"
#: Seconds a command may take before it counts as a hang (every case is small).
TIMEOUT = 300.0
#: Seconds from a signal to the end of the process (the 2 s grace period and the exit, on a
#: loaded 2-core machine), as in tests/blender/test_interrupt.py.
STOP_WITHIN = 8.0
#: compare without EEVEE and the denoised renders: what the cases look at is elsewhere.
FAST_COMPARE = ["--no-eevee", "--denoise-samples", "none"]

CLASSES = {
    "SEC": "security of names and scripts: scripts in a .blend, names that forge a Saved line or drive the terminal",
    "EXR": "passes files that are not plain EXR images (deep, a pipe, a device), a Material Index between materials",
    "JSON": "scene descriptions with absurd content (deep nesting, Weight 2, Depth as the thickness map)",
    "OUT": "outputs over inputs and failed writes (--json or --out naming an input, a full or read-only disk)",
    "CONC": "two runs started together writing one output",
    "MERGE": "merged references and their parts: no fingerprint, a damaged JSON, a passes file as a reference",
    "RESUME": "--skip-existing over a cut-short output, or a frame of another size or scene",
    "BLEND": "what the scene reader must see or name: node groups, textured inputs, an inactive output, Geometry "
    "Nodes, drivers, a render border, names that clean alike",
    "CLI": "flags misused, and messages that must name the flag typed",
    "INT": "Ctrl-C, SIGTERM and SIGHUP during a command",
    "EXRV": "pass values near float32's largest, a pass with an extra channel",
    "MAT": "a Subsurface Radius or Scale of zero",
    "UNIT": "the same scene 1000 times larger or smaller",
    "SCENE": "a compare with every subsurface material off screen",
    "CLI4": "`all` combined with a technique, `--frames ''`",
    "CACHE": "the compare's reference cache and a merged reference with absurd metadata or pixels",
    "VERIFY": "the .blend writes of bake and calibrate on a fit that succeeds",
    "KILL": "SIGKILL, then the same command again",
}


# --------------------------------------------------------------------------------------------
# Verdicts and what a run printed


@dataclass
class Verdict:
    status: str
    reason: str = ""


def handled(reason: str = "") -> Verdict:
    return Verdict(HANDLED, reason)


def not_handled(reason: str) -> Verdict:
    return Verdict(NOT_HANDLED, reason)


def not_run(reason: str) -> Verdict:
    return Verdict(NOT_RUN, reason)


def judge(problem: str | None, good: str = "") -> Verdict:
    """Not handled with ``problem`` as the reason, or handled (``good`` says how)."""
    return not_handled(problem) if problem else handled(good)


def visible(text: str) -> str:
    """``text`` on one line, every control character written as an escape (names in these cases
    hold newlines and terminal escapes, which this report must not pass on)."""
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in text)


def clip(text: str, n: int = 220) -> str:
    text = visible(text)
    return text if len(text) <= n else text[: n - 3] + "..."


@dataclass
class Run:
    shown: str  # the command as typed, the work folder written WORK
    code: int | None
    out: str
    err: str
    seconds: float
    changed: list[str] = field(default_factory=list)
    timed_out: bool = False
    stopped: float | None = None  # seconds from the signal to the end of the process
    signalled: bool = True

    @property
    def text(self) -> str:
        return self.out + self.err

    def said(self) -> str:
        """The command's own message lines on stderr (``sss_lab COMMAND: ...``), else its last line."""
        lines = [ln for ln in self.err.splitlines() if ln.strip()]
        own = [ln for ln in lines if ln.startswith("sss_lab")]
        if own:
            return " / ".join(own)
        if lines:
            return lines[-1]
        out = [ln for ln in self.out.splitlines() if ln.strip()]
        return f"(stdout) {out[-1]}" if out else "(nothing printed)"

    def brief(self) -> str:
        if self.timed_out:
            return f"no result within {self.seconds:.0f} s (killed)"
        return f"exit {self.code}: {clip(self.said())}"


def refused(run: Run, code: int = 2, words: Iterable = (), absent: Iterable[str] = ()) -> str | None:
    """None when ``run`` is one clear refusal: exit ``code``, a message on stderr naming each of
    ``words`` (a tuple there: any one of its words), none of ``absent``; else what differs."""
    if run.code == 0:
        return f"exit 0: accepted where a refusal with exit {code} was expected ({clip(run.said())})"
    problems = []
    if run.code != code:
        problems.append(f"exit {run.code}, expected {code}")
    err = run.err.lower()
    if not run.err.strip():
        problems.append("nothing on stderr")
    for word in words:
        options = word if isinstance(word, tuple) else (word,)
        if not any(w.lower() in err for w in options):
            problems.append("the message does not name " + " or ".join(repr(w) for w in options))
    for word in absent:
        if word.lower() in err:
            problems.append(f"the message says {word!r}")
    if not problems:
        return None
    return "; ".join(problems) + f" ({clip(run.said())})"


def mentions(text: str, *words) -> bool:
    """Every one of ``words`` (a tuple: any of its words) occurs in ``text``, case aside."""
    text = text.lower()
    return all(any(w.lower() in text for w in (word if isinstance(word, tuple) else (word,))) for word in words)


def lines_with(text: str, *words) -> list[str]:
    return [ln for ln in text.splitlines() if mentions(ln, *words)]


# --------------------------------------------------------------------------------------------
# Files


def sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def digests(paths: Iterable[str]) -> dict[str, str]:
    """Hash of every regular file named or under a folder named (links followed for the names
    given, not inside folders)."""
    out = {}
    for path in paths:
        if os.path.isdir(path):
            for root, _, names in os.walk(path):
                for name in names:
                    p = os.path.join(root, name)
                    if os.path.isfile(p) and not os.path.islink(p):
                        out[p] = sha256(p)
        elif os.path.isfile(path):
            out[path] = sha256(path)
        else:
            out[path] = "(none)"
    return out


def cut_to(path: str, percent: int) -> None:
    """Keep the first ``percent`` % of ``path``."""
    data = open(path, "rb").read()
    open(path, "wb").write(data[: len(data) * percent // 100])


#: The names a temporary or a leftover takes: hidden files beside an output, ``.tmp``, Blender's
#: ``.blend1`` backup, SSS Lab's working folders in TMPDIR.
LEFTOVER = re.compile(r"^\.|\.tmp$|\.tmp\.|\.blend1$|^sss_lab_")


def leftovers(folder: str) -> list[str]:
    found = []
    for root, dirs, names in os.walk(folder):
        for name in dirs + names:
            if LEFTOVER.search(name):
                found.append(os.path.relpath(os.path.join(root, name), folder))
    return sorted(found)


BLEND_MAGIC = (b"BLENDER", b"\x28\xb5\x2f\xfd")  # plain, zstd-compressed


def is_blend(path: str) -> bool:
    try:
        with open(path, "rb") as f:
            return f.read(7).startswith(BLEND_MAGIC)
    except OSError:
        return False


# --------------------------------------------------------------------------------------------
# EXR files (OpenEXR's own module: the fixtures are edited and the outputs read without SSS Lab)


def exr_read(path: str) -> list[tuple[str, dict[str, np.ndarray]]]:
    import OpenEXR

    with OpenEXR.File(path, separate_channels=True) as f:
        return [(p.name(), {k: np.array(v.pixels) for k, v in p.channels.items()}) for p in f.parts]


def exr_write(path: str, parts: list[tuple[str, dict[str, np.ndarray]]], *, deep: bool = False) -> None:
    import OpenEXR

    if deep:  # one sample per pixel: each pixel an array of one value
        parts = [(name, {k: _one_sample(v) for k, v in channels.items()}) for name, channels in parts]
    kind = OpenEXR.deepscanline if deep else OpenEXR.scanlineimage
    compression = OpenEXR.ZIPS_COMPRESSION if deep else OpenEXR.ZIP_COMPRESSION
    out = [OpenEXR.Part({"compression": compression, "type": kind}, channels, name=name) for name, channels in parts]
    OpenEXR.File(out).write(path)


def _one_sample(pixels: np.ndarray) -> np.ndarray:
    out = np.empty(pixels.shape, dtype=object)
    for index in np.ndindex(pixels.shape):
        out[index] = np.array([pixels[index]], dtype=pixels.dtype)
    return out


#: Reads every pixel of every part; any message of the library counts (it reports some damage
#: on stderr and returns what it could read rather than raising).
READS_WHOLE = r"""
import sys, OpenEXR
with OpenEXR.File(sys.argv[-1], separate_channels=True) as f:
    for part in f.parts:
        for channel in part.channels.values():
            channel.pixels.sum()
"""


def exr_problem(path: str) -> str | None:
    """None when ``path`` reads whole (every part, every pixel, without a word from OpenEXR),
    else why not."""
    if not os.path.isfile(path):
        return "missing"
    done = subprocess.run([PYTHON, "-c", READS_WHOLE, path], capture_output=True, text=True, timeout=TIMEOUT)
    if done.returncode != 0 or done.stderr.strip():
        lines = [ln for ln in done.stderr.splitlines() if ln.strip()]
        return f"does not read whole ({clip(lines[-1] if lines else f'exit {done.returncode}', 100)})"
    return None


def exr_size(path: str) -> tuple[int, int]:
    name, channels = exr_read(path)[0]
    h, w = next(iter(channels.values())).shape[:2]
    return w, h


def channel(parts, full_name: str) -> np.ndarray:
    for _, channels in parts:
        if full_name in channels:
            return channels[full_name]
    raise KeyError(full_name)


def image_layers(path: str) -> dict[str, np.ndarray]:
    """The ``SSSLab.<technique>.Image`` layers of an output as H x W x 3 arrays."""
    layers: dict[str, list] = {}
    for _name, channels in exr_read(path):
        for key, pixels in channels.items():
            m = re.match(r"^(SSSLab\.[^.]+\.Image)\.([RGB])$", key)
            if m:
                layers.setdefault(m.group(1), [None] * 3)["RGB".index(m.group(2))] = pixels
    return {k: np.stack(v, axis=-1) for k, v in layers.items() if all(p is not None for p in v)}


def sss_layers(path: str) -> dict[str, np.ndarray]:
    out: dict[str, list] = {}
    for _name, channels in exr_read(path):
        for key, pixels in channels.items():
            m = re.match(r"^SSSLab\.([^.]+)\.SSS\.([RGB])$", key)
            if m:
                out.setdefault(m.group(1), [None] * 3)["RGB".index(m.group(2))] = pixels
    return {k: np.stack(v, axis=-1).astype(np.float64) for k, v in out.items()}


# --------------------------------------------------------------------------------------------
# The .blend fixtures, built with bpy in a subprocess


BUILD_BLENDS = r'''
import math, os, sys
import bpy

scenes, out, markers = sys.argv[-3:]
bpy.context.preferences.filepaths.use_scripts_auto_execute = False


def load(name):
    bpy.ops.wm.open_mainfile(filepath=os.path.join(scenes, name + ".blend"), load_ui=False, use_scripts=False)


def save(name):
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, name + ".blend"), copy=True)


def skin():
    mat = bpy.data.materials["Skin"]
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    output = next(n for n in mat.node_tree.nodes if n.type == "OUTPUT_MATERIAL")
    return mat, mat.node_tree, bsdf, output


def add_uv(obj):
    """A spherical projection, enough for an image bake."""
    mesh = obj.data
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        x, y, z = mesh.vertices[loop.vertex_index].co
        r = max((x * x + y * y + z * z) ** 0.5, 1e-9)
        u = 0.5 + math.atan2(y, x) / (2 * math.pi)
        uv.data[loop.index].uv = (u, 0.5 + math.asin(max(-1.0, min(1.0, z / r))) / math.pi)


# A text block registered to run when the file loads, and a light driven by an expression: both
# write a marker file if they run.
load("head_frontlit")
text = bpy.data.texts.new("autorun.py")
text.write(f"open({os.path.join(markers, 'm1')!r}, 'w').write('ran')\n")
text.use_module = True
save("hostile")

load("head_frontlit")
fc = bpy.data.lights["Fill"].driver_add("energy")
fc.driver.type = "SCRIPTED"
fc.driver.expression = f"open({os.path.join(markers, 'm2')!r}, 'w').write('ran') * 0 + 0.3"
save("hostile_driver")

load("head_frontlit")
skin()[0].name = "Skin\nSaved: '/etc/passwd'\x1b[2J"
save("nameinject")

load("head_frontlit")
add_uv(bpy.data.objects["Head"])
save("head_uv")
head_a = bpy.data.objects["Head"]
head_a.name = head_a.data.name = "Head A"
twin = head_a.copy()
twin.data = head_a.data.copy()
twin.name = twin.data.name = "Head_A"
twin.location.x += 0.25
bpy.context.scene.collection.objects.link(twin)
save("same_clean_names")

load("head_frontlit")
mat, tree, bsdf, output = skin()
group = bpy.data.node_groups.new("SkinShader", "ShaderNodeTree")
group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
inner = group.nodes.new("ShaderNodeBsdfPrincipled")
inner.subsurface_method = bsdf.subsurface_method
for i, socket in enumerate(bsdf.inputs):
    if hasattr(socket, "default_value"):
        try:
            inner.inputs[i].default_value = socket.default_value
        except (TypeError, ValueError, AttributeError):
            pass
group.links.new(inner.outputs[0], group.nodes.new("NodeGroupOutput").inputs[0])
node = tree.nodes.new("ShaderNodeGroup")
node.node_tree = group
tree.links.new(node.outputs[0], output.inputs["Surface"])
tree.nodes.remove(bsdf)
save("node_group_sss")

for name, kind, out_socket, socket in (
    ("textured_base_color", "ShaderNodeTexChecker", "Color", "Base Color"),
    ("textured_radius", "ShaderNodeTexNoise", "Color", "Subsurface Radius"),
    ("textured_weight", "ShaderNodeTexChecker", "Fac", "Subsurface Weight"),
):
    load("head_frontlit")
    mat, tree, bsdf, output = skin()
    tex = tree.nodes.new(kind)
    tex.inputs["Scale"].default_value = 12.0
    tree.links.new(tex.outputs[out_socket], bsdf.inputs[socket])
    save(name)

load("head_frontlit")
mat, tree, bsdf, output = skin()
active = tree.nodes.new("ShaderNodeOutputMaterial")
tree.links.new(tree.nodes.new("ShaderNodeBsdfDiffuse").outputs[0], active.inputs["Surface"])
active.is_active_output = True
save("two_outputs")

load("head_frontlit")
r = bpy.context.scene.render
r.use_border, r.use_crop_to_border = True, True
r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.25, 0.75
save("render_border")

load("head_frontlit")
mat = skin()[0]
head = bpy.data.objects["Head"]
head.material_slots[0].material = bpy.data.materials.new("Plain")
ng = bpy.data.node_groups.new("SetSkin", "GeometryNodeTree")
ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
set_mat = ng.nodes.new("GeometryNodeSetMaterial")
set_mat.inputs["Material"].default_value = mat
ng.links.new(ng.nodes.new("NodeGroupInput").outputs[0], set_mat.inputs["Geometry"])
ng.links.new(set_mat.outputs["Geometry"], ng.nodes.new("NodeGroupOutput").inputs[0])
head.modifiers.new("SetSkin", "NODES").node_group = ng
save("gn_material")

load("head_frontlit")
mat, tree, bsdf, output = skin()
weight = bsdf.inputs["Subsurface Weight"]
weight.default_value = 0.0
fc = weight.driver_add("default_value")
fc.driver.type = "SCRIPTED"
fc.driver.expression = "__import__('math').floor(1.5)"
save("driver_weight")

load("head_frontlit")
bpy.context.scene.camera.rotation_euler.z += math.pi
save("camera_away")
'''

#: Opens a .blend with scripts allowed: does its script write the marker? (the hostile files
#: must hold scripts that do run, or their cases check nothing).
SCRIPTS_RUN = r"""
import sys, bpy
bpy.context.preferences.filepaths.use_scripts_auto_execute = True
bpy.ops.wm.open_mainfile(filepath=sys.argv[-1], load_ui=False, use_scripts=True)
bpy.context.view_layer.update()
bpy.context.scene.frame_set(bpy.context.scene.frame_current)
"""

#: A command run inside the process with Blender's preferences allowing scripts to run, as
#: ``blender -y`` or a user's "Auto Run Python Scripts" would have them.
AUTORUN_CLI = r"""
import sys, json, bpy
bpy.context.preferences.filepaths.use_scripts_auto_execute = True
from sss_lab.addon import cli
sys.exit(cli.main(json.loads(sys.argv[-1])))
"""

OPENS = r"""
import sys, bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[-1], load_ui=False, use_scripts=False)
"""


class FixtureError(RuntimeError):
    pass


class Work:
    """The run's work folder: fixtures made once, on first use, and a folder per case."""

    def __init__(self, root: str):
        self.root = root
        self.made: dict[str, object] = {}
        self.fixture_files: list[str] = []
        self.mount_ok: bool | None = None
        self.mount_reason = ""

    def show(self, text: str) -> str:
        return text.replace(self.root, "WORK")

    def path(self, *parts: str) -> str:
        return os.path.join(self.root, *parts)

    def _run(self, argv: list[str], what: str, timeout: float = TIMEOUT) -> subprocess.CompletedProcess:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, cwd=self.root)
        if done.returncode != 0:
            raise FixtureError(
                f"{what}: exit {done.returncode}: {clip(done.stderr.strip()[-300:] or done.stdout[-300:])}"
            )
        return done

    def sss(self, *args: str, what: str) -> subprocess.CompletedProcess:
        return self._run([PYTHON, "-m", "sss_lab", *args], what)

    def fixture(self, name: str):
        if name not in self.made:
            start = time.perf_counter()
            try:
                self.made[name] = getattr(self, f"_make_{name}")()
            except (FixtureError, subprocess.TimeoutExpired) as exc:
                self.made[name] = FixtureError(f"fixture {name}: {exc}")
            took = time.perf_counter() - start
            state = "failed" if isinstance(self.made[name], FixtureError) else "made"
            print(f"  (fixture {name} {state} in {took:.1f} s)", flush=True)
            self.fixture_files = sorted(
                {p for v in self.made.values() if not isinstance(v, Exception) for p in _files_of(v)}
            )
        value = self.made[name]
        if isinstance(value, FixtureError):
            raise value
        return value

    def _make_scenes(self) -> dict:
        out = self.path("scenes")
        self._run(
            [PYTHON, os.path.join(ROOT, "sample_blends", "build_scenes.py"), "head_frontlit", "backlit_thin"]
            + ["--out", out],
            "build_scenes.py",
        )
        return {"scene": os.path.join(out, "head_frontlit.blend"), "backlit": os.path.join(out, "backlit_thin.blend")}

    def scene(self) -> str:
        return self.fixture("scenes")["scene"]

    def backlit(self) -> str:
        return self.fixture("scenes")["backlit"]

    def _make_passes(self) -> dict:
        out = self.path("head")
        self.sss("render", self.scene(), "--out", out, "--resolution", "48x48", "--pass-samples", "4", what="render")
        return {"exr": os.path.join(out, "passes_0001.exr"), "json": os.path.join(out, "passes_0001.json")}

    def _make_parts(self) -> dict:
        out = self.path("parts")
        self.sss(
            "reference",
            self.scene(),
            "--out",
            out,
            "--seeds",
            "1-2",
            "--samples",
            "4",
            "--resolution",
            "48x48",
            what="reference",
        )
        return {"dir": out}

    def _make_ref(self) -> dict:
        out = self.path("ref", "ref.exr")
        os.makedirs(os.path.dirname(out))
        self.sss("merge-reference", self.fixture("parts")["dir"], "--out", out, what="merge-reference")
        return {"exr": out, "json": out[:-4] + ".json"}

    def _make_cache(self) -> dict:
        out = self.path("cmp")
        self.sss("compare", self.scene(), "--out", out, *CACHE_COMPARE, *FAST_COMPARE, what="compare")
        cache = os.path.join(out, "cache")
        entry = None
        for name in sorted(os.listdir(cache)):
            if name.endswith(".json"):
                meta = json.load(open(os.path.join(cache, name)))
                if meta.get("samples") == 4 and meta.get("seed") == 0 and not meta.get("method"):
                    entry = name[:-5]
        if entry is None:
            raise FixtureError("compare: no cache entry of the reference (4 samples, seed 0)")
        return {"dir": cache, "entry": entry}

    def _make_blends(self) -> dict:
        out, markers = self.path("blends"), self.path("m")
        os.makedirs(out)
        os.makedirs(markers)
        scenes = os.path.dirname(self.scene())
        self._run([PYTHON, "-c", BUILD_BLENDS, scenes, out, markers], "building the .blend files")
        # Controls: with scripts allowed, the hostile files' scripts do run.
        control = {}
        for blend, marker in (("hostile", "m1"), ("hostile_driver", "m2")):
            subprocess.run(
                [PYTHON, "-c", SCRIPTS_RUN, os.path.join(out, blend + ".blend")], capture_output=True, timeout=TIMEOUT
            )
            control[blend] = os.path.exists(os.path.join(markers, marker))
        for name in os.listdir(markers):
            os.remove(os.path.join(markers, name))
        # Neutral file names: what a command prints of a path must not hold the words a case
        # looks for in its messages ("driver", "border", "group", "radius" ...).
        names = sorted(n[:-6] for n in os.listdir(out) if n.endswith(".blend"))
        for i, n in enumerate(names):
            os.rename(os.path.join(out, n + ".blend"), os.path.join(out, f"f{i:02d}.blend"))
        paths = {n: os.path.join(out, f"f{i:02d}.blend") for i, n in enumerate(names)}
        return {
            "dir": out,
            "markers": markers,
            "control": control,
            **paths,
        }

    def blend(self, name: str) -> str:
        return self.fixture("blends")[name]

    def can_mount(self) -> bool:
        """Whether a tmpfs can be mounted in a private mount namespace here (``unshare -rm``)."""
        if self.mount_ok is None:
            check_dir = self.path("mount_check")
            os.makedirs(check_dir, exist_ok=True)
            try:
                done = subprocess.run(
                    ["unshare", "-rm", "sh", "-c", f"mount -t tmpfs -o size=16k tmpfs {check_dir}"],
                    capture_output=True,
                    text=True,
                    timeout=30,
                )
                self.mount_ok = done.returncode == 0
                self.mount_reason = done.stderr.strip()
            except (OSError, subprocess.TimeoutExpired) as exc:
                self.mount_ok, self.mount_reason = False, str(exc)
        return self.mount_ok


CACHE_COMPARE = ["--resolution", "32x32", "--reference-samples", "4", "--pass-samples", "2", "--bias-samples", "0"]


def _files_of(value) -> list[str]:
    if isinstance(value, dict):
        out = []
        for v in value.values():
            if isinstance(v, str) and os.path.isfile(v):
                out.append(v)
            elif isinstance(v, str) and os.path.isdir(v):
                out += [os.path.join(r, n) for r, _, names in os.walk(v) for n in names]
        return out
    return []


# --------------------------------------------------------------------------------------------
# A case's runs


def _preexec(limit_as: int | None):
    def reset():
        # A harness started in the background (``&``, nohup) passes on ignored signals; a user's
        # shell does not.
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(signum, signal.SIG_DFL)
        if limit_as:
            resource.setrlimit(resource.RLIMIT_AS, (limit_as, limit_as))

    return reset


class Proc:
    def __init__(self, popen, out_path, err_path, shown, before, inputs, start):
        self.popen, self.out_path, self.err_path = popen, out_path, err_path
        self.shown, self.before, self.inputs, self.start = shown, before, inputs, start

    def stdout_so_far(self) -> str:
        with open(self.out_path, errors="replace") as f:
            return f.read()


class Ctx:
    def __init__(self, work: Work, case_id: str, number: int):
        self.work = work
        # A number, not the case's id: what a command prints of a path must not hold the words
        # the case looks for in its messages.
        self.dir = work.path("cases", f"{number:02d}")
        self.logs = work.path("logs", case_id)
        self.tmp = os.path.join(self.dir, "tmp")
        for d in (self.dir, self.logs, self.tmp):
            os.makedirs(d, exist_ok=True)
        self.runs: list[Run] = []

    def path(self, *parts: str) -> str:
        return os.path.join(self.dir, *parts)

    # -- starting and ending processes

    def start(self, argv: list[str], shown: str, *, inputs=(), env=None, limit_as=None) -> Proc:
        n = len(os.listdir(self.logs)) // 2
        out_path, err_path = os.path.join(self.logs, f"{n:02d}.out"), os.path.join(self.logs, f"{n:02d}.err")
        full_env = dict(os.environ, TMPDIR=self.tmp, PYTHONUNBUFFERED="1", **(env or {}))
        inputs = [*inputs, *self.work.fixture_files]
        before = digests(inputs)
        with open(out_path, "w") as out, open(err_path, "w") as err:
            popen = subprocess.Popen(
                argv,
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=err,
                cwd=self.dir,
                env=full_env,
                start_new_session=True,
                preexec_fn=_preexec(limit_as),
            )
        return Proc(popen, out_path, err_path, shown, before, inputs, time.perf_counter())

    def finish(self, proc: Proc, timeout: float = TIMEOUT, *, signalled_at: float | None = None) -> Run:
        timed_out = False
        try:
            remaining = max(1.0, timeout - (time.perf_counter() - proc.start))
            proc.popen.wait(remaining)
        except subprocess.TimeoutExpired:
            timed_out = True
            try:
                os.killpg(proc.popen.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.popen.wait()
        end = time.perf_counter()
        after = digests(proc.inputs)
        changed = [self.work.show(p) for p, h in proc.before.items() if after.get(p) != h]
        with open(proc.out_path, errors="replace") as f:
            out = f.read()
        with open(proc.err_path, errors="replace") as f:
            err = f.read()
        run = Run(proc.shown, proc.popen.returncode, out, err, end - proc.start, changed, timed_out)
        if signalled_at is not None:
            run.stopped = end - signalled_at
        self.runs.append(run)
        return run

    def shown(self, args) -> str:
        return self.work.show(shlex.join(["python", "-m", "sss_lab", *map(str, args)]))

    def sss(self, *args, inputs=(), timeout: float = TIMEOUT, env=None, limit_as=None, note: str = "") -> Run:
        """``python -m sss_lab ARGS`` to its end (killed after ``timeout`` s)."""
        args = [str(a) for a in args]
        shown = self.shown(args) + (f"   # {note}" if note else "")
        proc = self.start([PYTHON, "-m", "sss_lab", *args], shown, inputs=inputs, env=env, limit_as=limit_as)
        return self.finish(proc, timeout)

    def sss_autorun(self, *args, inputs=()) -> Run:
        """The command inside a process whose Blender preferences allow scripts to run."""
        args = [str(a) for a in args]
        shown = self.work.show(
            "python -c 'import bpy; bpy.context.preferences.filepaths.use_scripts_auto_execute = True; "
            f"from sss_lab.addon import cli; cli.main({args!r})'"
        )
        proc = self.start([PYTHON, "-c", AUTORUN_CLI, json.dumps(args)], shown, inputs=inputs)
        return self.finish(proc)

    def together(self, *commands: list, inputs=()) -> list[Run]:
        """Several commands started at once."""
        procs = [
            self.start([PYTHON, "-m", "sss_lab", *map(str, c)], self.shown(c) + "   # started together", inputs=inputs)
            for c in commands
        ]
        return [self.finish(p) for p in procs]

    def sss_signal(
        self,
        *args,
        signum: int,
        when_line: str | None = None,
        when: Callable[[], bool] | None = None,
        when_shown: str = "",
        after: float = 0.0,
        timeout: float = 120.0,
        env=None,
        inputs=(),
        poll: float = 0.005,
    ) -> Run:
        """Start the command; when stdout shows ``when_line`` (or ``when()`` holds, which
        ``when_shown`` says in words), wait ``after`` s and send ``signum`` to it; run.signalled is
        False when it ended first."""
        args = [str(a) for a in args]
        condition = repr(when_line) if when_line else when_shown
        name = signal.Signals(signum).name
        shown = self.shown(args) + f"   # {name} {after:g} s after {condition}"
        proc = self.start([PYTHON, "-m", "sss_lab", *args], shown, inputs=inputs, env=env)
        deadline = proc.start + timeout
        while proc.popen.poll() is None and time.perf_counter() < deadline:
            if (when_line and when_line in proc.stdout_so_far()) or (when and when()):
                break
            time.sleep(poll)
        if after:
            time.sleep(after)
        if proc.popen.poll() is not None or time.perf_counter() >= deadline:
            run = self.finish(proc, timeout)
            run.signalled = False
            return run
        proc.popen.send_signal(signum)
        return self.finish(proc, timeout + 120.0, signalled_at=time.perf_counter())

    def sss_on_disks(self, *args, disks: dict[str, str], inputs=(), timeout: float = TIMEOUT) -> Run | None:
        """The command with a tmpfs mounted (``mount -o OPTIONS``) at each folder of ``disks``, in a
        private mount namespace; what each held at the end is copied to FOLDER.after. None when no
        such namespace can be made here."""
        if not self.work.can_mount():
            return None
        args = [str(a) for a in args]
        script = ["set -e"]
        for folder, options in disks.items():
            os.makedirs(folder, exist_ok=True)
            script.append(f"mount -t tmpfs -o {shlex.quote(options)} tmpfs {shlex.quote(folder)} || exit 97")
        script += ["set +e", '"$@"', "rc=$?"]
        for folder in disks:
            script.append(
                f"mkdir -p {shlex.quote(folder + '.after')} && cp -a {shlex.quote(folder)}/. "
                f"{shlex.quote(folder + '.after')}/"
            )
        script.append("exit $rc")
        mounts = ", ".join(f"{self.work.show(f)}: tmpfs -o {o}" for f, o in disks.items())
        shown = f"({mounts}) " + self.shown(args)
        argv = ["unshare", "-rm", "sh", "-c", "\n".join(script), "sh", PYTHON, "-m", "sss_lab", *args]
        run = self.finish(self.start(argv, shown, inputs=inputs), timeout)
        if run.code == 97:
            self.runs.remove(run)
            return None
        return run

    # -- inputs made for the case

    def passes(
        self,
        *,
        exr: Callable | None = None,
        desc: Callable | None = None,
        name: str = "passes_0001",
        deep: bool = False,
    ) -> str:
        """A copy of the fixture's passes (EXR and JSON) in the case's folder, edited by ``exr(parts)``
        and ``desc(description)``; the copy's EXR path."""
        src = self.work.fixture("passes")
        dst = self.path(name + ".exr")
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        if exr or deep:
            parts = exr_read(src["exr"])
            if exr:
                exr(parts)
            exr_write(dst, parts, deep=deep)
        else:
            shutil.copyfile(src["exr"], dst)
        description = json.load(open(src["json"]))
        if desc:
            desc(description)
        with open(dst[:-4] + ".json", "w") as f:
            json.dump(description, f, indent=2)
        return dst

    def ref(self, *, edit: Callable | None = None, text: str | None = None) -> str:
        """A copy of the merged reference (ref.exr, ref.json) in the case's folder; its JSON edited."""
        src = self.work.fixture("ref")
        dst = self.path("ref.exr")
        shutil.copyfile(src["exr"], dst)
        if text is not None:
            open(self.path("ref.json"), "w").write(text)
        else:
            data = json.load(open(src["json"]))
            if edit:
                edit(data)
            json.dump(data, open(self.path("ref.json"), "w"), indent=2)
        return dst

    def parts(self, name: str = "P") -> str:
        dst = self.path(name)
        shutil.copytree(self.work.fixture("parts")["dir"], dst)
        return dst


def skin_mask(parts, description) -> np.ndarray:
    index = description["materials"][0]["index"] if description else 1
    return np.isclose(channel(parts, "ViewLayer.Material Index.X"), index)


def description_of(c: Ctx) -> dict:
    return json.load(open(c.work.fixture("passes")["json"]))


# --------------------------------------------------------------------------------------------
# The cases


@dataclass
class Case:
    id: str
    cls: str
    what: str
    run: Callable[[Ctx], Verdict]


CASES: list[Case] = []


def case(cid: str, cls: str, what: str):
    def register(fn):
        CASES.append(Case(cid, cls, what, fn))
        return fn

    return register


def forged_or_raw(run: Run, own: Iterable[str] = ()) -> str | None:
    """A ``Saved:`` line naming a file the command did not write (``own``: the paths it may name,
    or prefixes), or a raw control character (ESC, BEL) in what it printed."""
    for line in run.text.splitlines():
        if line.startswith("Saved:"):
            m = re.match(r"^Saved: '(.*)'$", line)
            path = m.group(1) if m else line[6:].strip()
            if not (os.path.exists(path) and any(path.startswith(o) for o in own)):
                return f"a forged Saved line: {clip(line, 80)!r}"
    for ch in ("\x1b", "\x07"):
        if ch in run.text:
            return f"a raw {visible(ch)} written to the terminal"
    return None


# SEC ---------------------------------------------------------------------------------------


def _autorun(c: Ctx, blend: str, marker: str, script: str, command: list[str]) -> Verdict:
    fx = c.work.fixture("blends")
    if not fx["control"][blend]:
        return not_run(f"the {script} in the .blend does not run even with scripts allowed: nothing to check")
    run = c.sss_autorun(*command)
    if os.path.exists(os.path.join(fx["markers"], marker)):
        os.remove(os.path.join(fx["markers"], marker))
        return not_handled(f"code from the .blend ran (its {script} wrote a file); {run.brief()}")
    if run.code != 0:
        return not_handled(f"nothing ran, but {run.brief()}")
    said = "said so" if mentions(run.text, "scripts were not run") else "nothing said"
    return handled(f"the {script} did not run, exit 0 ({said})")


@case("sec09_prefs_autorun_scan", "SEC", "scan with Blender's preferences allowing scripts: a registered text block")
def sec09(c: Ctx) -> Verdict:
    return _autorun(c, "hostile", "m1", "text block", ["scan", c.work.blend("hostile")])


@case("sec10_prefs_autorun_render_driver", "SEC", "render with scripts allowed: a light driven by an expression")
def sec10(c: Ctx) -> Verdict:
    blend = c.work.blend("hostile_driver")
    return _autorun(
        c,
        "hostile_driver",
        "m2",
        "driver",
        ["render", blend, "--out", c.path("o"), "--resolution", "48x48", "--pass-samples", "4"],
    )


def _name_in_description(c: Ctx, name: str) -> Verdict:
    def rename(d):
        d["materials"][0]["name"] = name

    exr = c.passes(desc=rename)
    run = c.sss("apply", exr, "--methods", "burley", "--out", c.path("out.exr"))
    problem = forged_or_raw(run, [c.dir])
    if problem:
        return not_handled(f"{problem}; exit {run.code}")
    if run.code not in (0, 2):
        return not_handled(run.brief())
    return handled(f"exit {run.code}, the name printed escaped")


@case("sec14_name_newline_saved", "SEC", "apply: a material name holding a newline and a `Saved:` line")
def sec14(c: Ctx) -> Verdict:
    return _name_in_description(c, "Skin\nSaved: '/etc/passwd'")


@case("sec15_name_ansi", "SEC", "apply: a material name holding terminal escapes (title, clear screen)")
def sec15(c: Ctx) -> Verdict:
    return _name_in_description(c, "Skin\x1b]0;owned\x07\x1b[2J")


@case("sec16_blend_name_scan", "SEC", "scan a .blend whose material name holds a newline, `Saved:` and ESC")
def sec16(c: Ctx) -> Verdict:
    run = c.sss("scan", c.work.blend("nameinject"))
    problem = forged_or_raw(run)
    if problem:
        return not_handled(f"{problem}; exit {run.code}")
    return judge(None if run.code == 0 else run.brief(), "exit 0, the name printed escaped")


@case("sec17_blend_name_render_apply", "SEC", "render and apply a .blend whose material name holds `Saved:` and ESC")
def sec17(c: Ctx) -> Verdict:
    out = c.path("o")
    runs = [c.sss("render", c.work.blend("nameinject"), "--out", out, "--resolution", "48x48", "--pass-samples", "4")]
    if runs[0].code == 0:
        runs.append(c.sss("apply", os.path.join(out, "passes_0001.exr"), "--methods", "burley"))
    for run in runs:
        problem = forged_or_raw(run, [c.dir])
        if problem:
            return not_handled(f"{run.shown.split()[3]}: {problem}")
        if run.code != 0:
            return not_handled(run.brief())
    return handled("exit 0 twice, the name printed escaped")


# EXR ---------------------------------------------------------------------------------------


@case("exr06_deep", "EXR", "apply on a deep scanline EXR holding Blender's pass names")
def exr06(c: Ctx) -> Verdict:
    exr = c.passes(deep=True)
    run = c.sss("apply", exr, "--methods", "all", "--out", c.path("out.exr"))
    return judge(
        refused(run, 2, ["deep"]) or (os.path.exists(c.path("out.exr")) and "an output was written"), run.brief()
    )


@case("exr17_fifo", "EXR", "apply on a named pipe that nobody writes")
def exr17(c: Ctx) -> Verdict:
    os.makedirs(c.path("f"))
    fifo = c.path("f", "passes_0001.exr")
    os.mkfifo(fifo)
    shutil.copyfile(c.work.fixture("passes")["json"], c.path("f", "passes_0001.json"))
    run = c.sss("apply", fifo, "--methods", "burley", "--out", c.path("out.exr"), timeout=60)
    os.remove(fifo)
    return judge(refused(run, 2, [("pipe", "fifo", "not a regular file")], absent=["no such"]), run.brief())


@case("exr18_dev_zero", "EXR", "apply on /dev/zero (a character device)")
def exr18(c: Ctx) -> Verdict:
    desc = c.passes()[:-4] + ".json"
    run = c.sss(
        "apply", "/dev/zero", "--methods", "burley", "--description", desc, "--out", c.path("out.exr"), timeout=60
    )
    return judge(refused(run, 2, [("device", "not a regular file")], absent=["no such"]), run.brief())


@case("exr20_matindex_fraction", "EXR", "apply where the Material Index is 1.5 on the skin")
def exr20(c: Ctx) -> Verdict:
    d = description_of(c)

    def half(parts):
        key = "ViewLayer.Material Index.X"
        for _, channels in parts:
            if key in channels:
                channels[key] = np.where(skin_mask(parts, d), channels[key] + 0.5, channels[key]).astype(np.float32)

    exr = c.passes(exr=half)
    run = c.sss("apply", exr, "--methods", "all", "--out", c.path("out.exr"))
    said = lines_with(run.text, "material index", ("integer", "whole", "fraction", "between"))
    if run.code == 2 and said:
        return handled(run.brief())
    if run.code == 0 and said:
        return handled(f"exit 0 with a note: {clip(said[0])}")
    computed = lines_with(run.out, "material(s) computed")
    shown = f"'{clip(computed[0].strip(), 80)}' for each technique" if computed else run.brief()
    return not_handled(f"exit {run.code}, no word of a non-integer Material Index: {shown}")


# JSON --------------------------------------------------------------------------------------


@case("js03_deep_nesting", "JSON", "apply with a scene description of 100000 nested arrays")
def js03(c: Ctx) -> Verdict:
    exr = c.passes()
    open(exr[:-4] + ".json", "w").write("[" * 100000 + "]" * 100000)
    run = c.sss("apply", exr, "--methods", "all", "--out", c.path("out.exr"))
    return judge(refused(run, 2, ["passes_0001.json"], absent=["internal error"]), run.brief())


@case("js17_weight_two", "JSON", "apply with subsurface_weight 2.0 in the description (Blender's range is 0..1)")
def js17(c: Ctx) -> Verdict:
    exr = c.passes(desc=lambda d: d["materials"][0].update(subsurface_weight=2.0))
    run = c.sss("apply", exr, "--methods", "all", "--out", c.path("out.exr"))
    if run.code == 0 and lines_with(run.text, "weight", ("clamp", "1")):
        return handled("clamped with a note")
    return judge(refused(run, 2, ["subsurface_weight"]), run.brief())


@case("js28_thickness_aov_depth", "JSON", "apply STA with the description's thickness AOV naming the Depth pass")
def js28(c: Ctx) -> Verdict:
    exr = c.passes(desc=lambda d: d.update(thickness_aov="Depth"))
    run = c.sss("apply", exr, "--methods", "sta", "--out", c.path("out.exr"))
    if run.code == 0 and lines_with(run.text, "depth", "thickness"):
        return handled(f"exit 0 with a note: {clip(lines_with(run.text, 'depth', 'thickness')[0])}")
    return judge(refused(run, 2, ["depth"]), run.brief())


# OUT ---------------------------------------------------------------------------------------


def _blend_left(c: Ctx, folder_after: str, run: Run, name: str = "o.blend") -> str | None:
    """What a command that wrote a .blend on a small disk left there, judged as a user would:
    exit 1 and nothing left, or exit 0 and a .blend that opens."""
    left = sorted(os.listdir(folder_after)) if os.path.isdir(folder_after) else []
    target = os.path.join(folder_after, name)
    if run.code == 0:
        if not os.path.exists(target):
            return f"exit 0 but no {name}"
        opened = subprocess.run([PYTHON, "-c", OPENS, target], capture_output=True, text=True, timeout=TIMEOUT)
        if opened.returncode != 0:
            size = os.path.getsize(target)
            return f"exit 0 and 'Saved:' printed, but the {size}-byte {name} left on the disk does not open"
        return None
    problem = refused(run, 1, [("space", "full", "read-only", "read only")])
    if problem:
        return problem
    if left:
        return f"{run.brief()}; left on the disk: {left}"
    return None


@case("ou07_bake_full", "OUT", "bake-thickness --out on a full 64 KB disk")
def ou07(c: Ctx) -> Verdict:
    full = c.path("disk")
    run = c.sss_on_disks(
        "bake-thickness",
        c.work.scene(),
        "--out",
        os.path.join(full, "o.blend"),
        "--samples",
        "4",
        disks={full: "size=64k"},
    )
    if run is None:
        return not_run(f"no tmpfs can be mounted here ({c.work.mount_reason})")
    return judge(_blend_left(c, full + ".after", run), run.brief())


@case("ou08_bake_image_full", "OUT", "bake-thickness --target image with --image-dir on a full 64 KB disk")
def ou08(c: Ctx) -> Verdict:
    full = c.path("disk")
    run = c.sss_on_disks(
        "bake-thickness",
        c.work.blend("head_uv"),
        "--out",
        c.path("OUT.blend"),
        "--target",
        "image",
        "--image-size",
        "256",
        "--samples",
        "2",
        "--image-dir",
        os.path.join(full, "img"),
        disks={full: "size=64k"},
    )
    if run is None:
        return not_run(f"no tmpfs can be mounted here ({c.work.mount_reason})")
    problems = [refused(run, 1, [("space", "full")], absent=["OutputError("])]
    if "OutputError(" in run.out:
        problems.append("the reason printed only on stdout, as a Python repr (OutputError(28, ...))")
    left = [os.path.relpath(os.path.join(r, n), full + ".after") for r, _, ns in os.walk(full + ".after") for n in ns]
    if left:
        problems.append(f"left on the full disk: {left}")
    return judge("; ".join(p for p in problems if p), run.brief())


@case("ou15_calibrate_json_is_input", "OUT", "calibrate --json naming the input .blend")
def ou15(c: Ctx) -> Verdict:
    blend = c.path("IN.blend")
    shutil.copyfile(c.work.scene(), blend)
    run = c.sss(
        "calibrate",
        blend,
        "--out",
        c.path("OUT.blend"),
        "--resolution",
        "32x32",
        "--samples",
        "2",
        "--pass-samples",
        "2",
        "--json",
        blend,
        inputs=[blend],
    )
    if run.changed:
        return not_handled(f"the input changed: {run.changed}; {run.brief()}")
    problem = refused(run, 2, ["IN.blend"]) or (os.path.exists(c.path("OUT.blend")) and "OUT.blend written")
    return judge(problem, run.brief())


@case("ou16_calibrate_json_is_out", "OUT", "calibrate --json naming the same path as --out")
def ou16(c: Ctx) -> Verdict:
    out = c.path("OUT.blend")
    run = c.sss(
        "calibrate",
        c.work.backlit(),
        "--out",
        out,
        "--json",
        out,
        "--resolution",
        "32x32",
        "--samples",
        "2",
        "--pass-samples",
        "2",
    )
    if os.path.exists(out) and not is_blend(out):
        return not_handled(f"OUT.blend is not a .blend (the JSON took its place); {run.brief()}")
    return judge(refused(run, 2, ["OUT.blend"]), run.brief())


@case("ou19_bake_image_over_existing", "OUT", "bake-thickness --target image over an image it did not bake")
def ou19(c: Ctx) -> Verdict:
    images = c.path("OUT_thickness")
    os.makedirs(images)
    precious = os.path.join(images, "Head_thickness.exr")
    open(precious, "w").write("precious\n")
    run = c.sss(
        "bake-thickness",
        c.work.blend("head_uv"),
        "--out",
        c.path("OUT.blend"),
        "--target",
        "image",
        "--image-size",
        "64",
        "--samples",
        "2",
        inputs=[precious],
    )
    if run.changed:
        return not_handled(f"Head_thickness.exr replaced without --overwrite; {run.brief()}")
    problem = refused(run, 2, ["Head_thickness.exr"]) or (os.path.exists(c.path("OUT.blend")) and "OUT.blend written")
    return judge(problem, run.brief())


@case("ou20_merge_out_via_dir_link", "OUT", "merge-reference --overwrite with --out a part, through a linked folder")
def ou20(c: Ctx) -> Verdict:
    parts = c.parts()
    os.symlink(parts, c.path("ALIAS"))
    run = c.sss(
        "merge-reference", parts, "--out", c.path("ALIAS", "reference_seed_00001.exr"), "--overwrite", inputs=[parts]
    )
    if run.changed:
        return not_handled(f"parts changed: {[os.path.basename(p) for p in run.changed]}; {run.brief()}")
    return judge(refused(run, 2), run.brief())


@case("ou21_merge_out_sidecar_clash", "OUT", "merge-reference --overwrite whose output's JSON is a part's JSON")
def ou21(c: Ctx) -> Verdict:
    parts = c.parts()
    run = c.sss(
        "merge-reference",
        parts,
        "--out",
        os.path.join(parts, "reference_seed_00001.merged"),
        "--overwrite",
        inputs=[parts],
    )
    if run.changed:
        return not_handled(f"parts changed: {[os.path.basename(p) for p in run.changed]}; {run.brief()}")
    return judge(refused(run, 2), run.brief())


@case("ou22_merge_out_folder", "OUT", "merge-reference --out an existing folder")
def ou22(c: Ctx) -> Verdict:
    os.makedirs(c.path("X"))
    run = c.sss("merge-reference", c.work.fixture("parts")["dir"], "--out", c.path("X"))
    return judge(refused(run, 2, [("folder", "directory")]), run.brief())


@case("ou26_calibrate_ro", "OUT", "calibrate --out on a read-only file system")
def ou26(c: Ctx) -> Verdict:
    ro = c.path("disk")
    run = c.sss_on_disks(
        "calibrate",
        c.work.scene(),
        "--out",
        os.path.join(ro, "o.blend"),
        "--resolution",
        "64x64",
        "--samples",
        "16",
        "--pass-samples",
        "8",
        disks={ro: "ro,size=64k"},
    )
    if run is None:
        return not_run(f"no tmpfs can be mounted here ({c.work.mount_reason})")
    return judge(refused(run, 1, [("read-only", "read only")]), run.brief())


# CONC --------------------------------------------------------------------------------------


def _two_writers(c: Ctx, runs: list[Run], out: str) -> Verdict:
    codes = sorted(r.code for r in runs)
    listing = sorted(os.listdir(os.path.dirname(out)))
    shown = f"exits {[r.code for r in runs]}, folder {[n for n in listing if n != 'tmp']}"
    if codes == [0, 0]:
        return not_handled(f"both exit 0 without --overwrite (one replaced the other); {shown}")
    if codes != [0, 2]:
        return not_handled(
            f"expected one to write and one to refuse with 2; {shown}: " + " | ".join(clip(r.said(), 120) for r in runs)
        )
    loser = next(r for r in runs if r.code == 2)
    if not mentions(loser.err, "exists"):
        return not_handled(f"the refusal does not say the output exists: {clip(loser.said())}")
    if not is_blend(out):
        return not_handled(f"{os.path.basename(out)} is not a whole .blend; {shown}")
    return handled(f"one wrote, the other refused ({clip(loser.said(), 100)})")


@case("co03_two_bakes_same_out", "CONC", "two bake-thickness to one new --out started together")
def co03(c: Ctx) -> Verdict:
    out = c.path("OUT.blend")
    cmd = ["bake-thickness", c.work.scene(), "--out", out, "--samples", "4"]
    return _two_writers(c, c.together(cmd, cmd), out)


# MERGE -------------------------------------------------------------------------------------


@case("me09_no_fingerprint_two_scenes", "MERGE", "merge-reference on parts of two scenes whose JSON lack fingerprint")
def me09(c: Ctx) -> Verdict:
    p2 = c.path("P2")
    os.makedirs(p2)
    parts = c.work.fixture("parts")["dir"]
    for ext in (".exr", ".json"):
        shutil.copyfile(
            os.path.join(parts, "reference_seed_00001" + ext), os.path.join(p2, "reference_seed_00001" + ext)
        )
    other = c.sss(
        "reference", c.work.backlit(), "--out", c.path("B"), "--seeds", "5", "--samples", "4", "--resolution", "48x48"
    )
    if other.code != 0:
        return not_handled(f"the second part could not be made: {other.brief()}")
    for ext in (".exr", ".json"):
        shutil.copyfile(c.path("B", "reference_seed_00005" + ext), os.path.join(p2, "reference_seed_00005" + ext))
    for name in ("reference_seed_00001.json", "reference_seed_00005.json"):
        path = os.path.join(p2, name)
        data = json.load(open(path))
        data.pop("fingerprint", None)
        data.pop("scene", None)
        json.dump(data, open(path, "w"))
    run = c.sss("merge-reference", p2, "--out", c.path("M.exr"), inputs=[p2])
    return judge(refused(run, 2) or (os.path.exists(c.path("M.exr")) and "M.exr written"), run.brief())


def _accepted(run: Run, problem: str | None) -> str | None:
    """``problem`` with what compare printed of the reference it accepted."""
    said = lines_with(run.out, "reference:")
    if problem and run.code == 0 and said:
        return f"exit 0, taken as a reference: '{clip(said[0].split('.exr,', 1)[-1].strip(), 80)}'"
    return problem


def _compare_reference(c: Ctx, ref: str, **kw) -> Run:
    return c.sss(
        "compare",
        c.work.scene(),
        "--out",
        c.path("o"),
        "--resolution",
        "48x48",
        "--pass-samples",
        "2",
        "--bias-samples",
        "0",
        "--reference",
        ref,
        *FAST_COMPARE,
        inputs=[ref, ref[:-4] + ".json"],
        **kw,
    )


@case("me12_ref_json_damaged", "MERGE", "compare --reference whose JSON is cut short")
def me12(c: Ctx) -> Verdict:
    run = _compare_reference(c, c.ref(text='{"samples": 8, '))
    return judge(refused(run, 2, ["ref.json"]), run.brief())


@case("me13_ref_json_list", "MERGE", "compare --reference whose JSON is a list")
def me13(c: Ctx) -> Verdict:
    run = _compare_reference(c, c.ref(text="[1, 2]\n"))
    return judge(refused(run, 2, ["ref.json"]), run.brief())


@case("me14_ref_half_seeds_text", "MERGE", "compare --reference whose half_seeds hold text")
def me14(c: Ctx) -> Verdict:
    run = _compare_reference(c, c.ref(edit=lambda d: d.update(half_seeds=[[1], ["x"]])))
    return judge(refused(run, 2, ["ref.json", "half_seeds"]), run.brief())


@case("me17_ref_is_passes", "MERGE", "compare --reference given a passes EXR and its JSON")
def me17(c: Ctx) -> Verdict:
    src = c.work.fixture("passes")
    shutil.copyfile(src["exr"], c.path("R.exr"))
    shutil.copyfile(src["json"], c.path("R.json"))
    run = _compare_reference(c, c.path("R.exr"))
    return judge(_accepted(run, refused(run, 2, [("R.exr", "R.json")])), run.brief())


# RESUME ------------------------------------------------------------------------------------


def _render(c: Ctx, blend: str, out: str, *extra) -> Run:
    return c.sss("render", blend, "--out", out, "--resolution", "48x48", "--pass-samples", "4", *extra)


@case("re01_render_skip_truncated", "RESUME", "render --skip-existing over a frame cut to half its size")
def re01(c: Ctx) -> Verdict:
    out = c.path("o")
    first = _render(c, c.work.scene(), out)
    if first.code != 0:
        return not_handled(f"the first render failed: {first.brief()}")
    frame = os.path.join(out, "passes_0001.exr")
    cut_to(frame, 50)
    run = _render(c, c.work.scene(), out, "--skip-existing")
    if run.code == 2:
        return handled(run.brief())
    problem = exr_problem(frame)
    return judge(
        problem and f"{run.brief()}; passes_0001.exr kept cut short ({problem})",
        f"exit {run.code}, the frame rendered again",
    )


@case("re02_render_skip_other_resolution", "RESUME", "render --resolution 32x32 --skip-existing over a 48x48 frame")
def re02(c: Ctx) -> Verdict:
    out = c.path("o")
    first = _render(c, c.work.scene(), out)
    if first.code != 0:
        return not_handled(f"the first render failed: {first.brief()}")
    run = c.sss(
        "render", c.work.scene(), "--out", out, "--resolution", "32x32", "--pass-samples", "4", "--skip-existing"
    )
    if run.code == 2:
        return handled(run.brief())
    size = exr_size(os.path.join(out, "passes_0001.exr"))
    return judge(
        None if size == (32, 32) else f"{run.brief()}; a {size[0]}x{size[1]} frame kept for a 32x32 job",
        f"exit {run.code}, the frame rendered again at 32x32",
    )


@case(
    "re03_render_skip_other_blend", "RESUME", "render another .blend --skip-existing into a folder of this one's frame"
)
def re03(c: Ctx) -> Verdict:
    out = c.path("o")
    first = _render(c, c.work.scene(), out)
    if first.code != 0:
        return not_handled(f"the first render failed: {first.brief()}")
    run = _render(c, c.work.backlit(), out, "--skip-existing")
    if run.code == 2:
        return handled(run.brief())
    meta = json.load(open(os.path.join(out, "passes_0001.json"))).get("meta", {})
    kept = "backlit_thin" not in str(meta.get("file", ""))
    return judge(
        kept and f"{run.brief()}; head_frontlit's frame kept for backlit_thin's job",
        f"exit {run.code}, the frame rendered again",
    )


@case("re04_apply_skip_truncated_output", "RESUME", "apply --skip-existing over an output cut to 40 %")
def re04(c: Ctx) -> Verdict:
    exr = c.passes()
    first = c.sss("apply", exr, "--methods", "all")
    output = exr[:-4] + ".sss.exr"
    if first.code != 0 or not os.path.exists(output):
        return not_handled(f"the first apply failed: {first.brief()}")
    cut_to(output, 40)
    run = c.sss("apply", exr, "--methods", "burley", "--skip-existing")
    if run.code == 2:
        return handled(run.brief())
    problem = exr_problem(output)
    return judge(
        problem and f"{run.brief()}; the cut-short output kept ({problem})", f"exit {run.code}, the output made again"
    )


@case("re08_reference_skip_truncated", "RESUME", "reference --skip-existing over part 1 cut in half")
def re08(c: Ctx) -> Verdict:
    parts = c.parts()
    part = os.path.join(parts, "reference_seed_00001.exr")
    cut_to(part, 50)
    run = c.sss(
        "reference",
        c.work.scene(),
        "--out",
        parts,
        "--seeds",
        "1-2",
        "--samples",
        "4",
        "--resolution",
        "48x48",
        "--skip-existing",
    )
    if run.code == 2:
        return handled(run.brief())
    problem = exr_problem(part)
    kept = lines_with(run.out, "seed 1:", "skipped")
    said = f"'{clip(kept[0].split('] ', 1)[-1], 80)}'" if kept else run.brief()
    kept_cut = problem and f"exit {run.code}, the cut-short part 1 kept ({said}); it {problem}"
    return judge(kept_cut, f"exit {run.code}, part 1 rendered again")


# BLEND -------------------------------------------------------------------------------------


def _scan_lists(run: Run, material: str = "Skin") -> bool:
    return run.code == 0 and re.search(rf"^\s+{re.escape(material)}: ", run.out, re.M) is not None


@case("bl03_node_group_scan", "BLEND", "scan: the Principled BSDF inside a node group")
def bl03(c: Ctx) -> Verdict:
    run = c.sss("scan", c.work.blend("node_group_sss"))
    if _scan_lists(run) or lines_with(run.text, ("SkinShader", "node group")):
        return handled("the material listed" if _scan_lists(run) else "the group named")
    return not_handled(f"the material is not listed and the group not named; {run.brief()}")


def _render_lists(c: Ctx, blend: str, *names) -> tuple[Run, Verdict]:
    out = c.path("o")
    run = _render(c, blend, out)
    if run.code == 0:
        desc = json.load(open(os.path.join(out, "passes_0001.json")))
        found = [m["name"] for m in desc.get("materials", [])]
        if "Skin" in found:
            return run, handled(f"exit 0, Skin described ({found})")
        return run, not_handled(f"exit 0 but the description lists {found}")
    if lines_with(run.err, names):
        return run, handled(run.brief())
    return run, not_handled(run.brief())


@case("bl04_node_group_render", "BLEND", "render: the Principled BSDF inside a node group")
def bl04(c: Ctx) -> Verdict:
    return _render_lists(c, c.work.blend("node_group_sss"), "SkinShader", "node group")[1]


def _textured(c: Ctx, blend: str, socket: str, per_pixel_name: str) -> Verdict:
    out = c.path("o")
    runs = [_render(c, c.work.blend(blend), out)]
    if runs[0].code != 0:
        return not_handled(f"render: {runs[0].brief()}")
    runs.append(c.sss("apply", os.path.join(out, "passes_0001.exr"), "--methods", "burley"))
    if runs[1].code != 0:
        return not_handled(f"apply: {runs[1].brief()}")
    desc = json.load(open(os.path.join(out, "passes_0001.json")))
    per_pixel = [str(p) for m in desc.get("materials", []) for p in m.get("per_pixel", [])]
    said = [ln for r in runs for ln in lines_with(r.text, socket, ("linked", "textur", "per pixel", "per-pixel"))]
    if any(per_pixel_name in p for p in per_pixel):
        return handled(f"read per pixel from the render (per_pixel: {per_pixel})" + ("; said" if said else ""))
    if said:
        return handled(f"said: {clip(said[0], 140)}")
    return not_handled(f"the linked {socket} is neither read per pixel nor named (per_pixel: {per_pixel})")


@case("bl05_textured_base_color", "BLEND", "render and apply: Base Color from a texture")
def bl05(c: Ctx) -> Verdict:
    return _textured(c, "textured_base_color", "Base Color", "base_color")


@case("bl06_textured_radius", "BLEND", "render and apply: Subsurface Radius from a texture")
def bl06(c: Ctx) -> Verdict:
    return _textured(c, "textured_radius", "Subsurface Radius", "radius")


@case("bl07_textured_weight", "BLEND", "render and apply: Subsurface Weight from a checker (0 or 1)")
def bl07(c: Ctx) -> Verdict:
    return _textured(c, "textured_weight", "Subsurface Weight", "weight")


@case("bl09_two_outputs_scan", "BLEND", "scan: the SSS BSDF on an inactive Material Output, the active one diffuse")
def bl09(c: Ctx) -> Verdict:
    run = c.sss("scan", c.work.blend("two_outputs"))
    if run.code != 0 and run.code != 3:
        return not_handled(run.brief())
    return judge(
        _scan_lists(run) and "the material listed as scattering (Cycles renders it diffuse)",
        "the material not listed as scattering",
    )


@case("bl20_same_clean_names_bake", "BLEND", "bake-thickness --target image: meshes 'Head A' and 'Head_A'")
def bl20(c: Ctx) -> Verdict:
    run = c.sss(
        "bake-thickness",
        c.work.blend("same_clean_names"),
        "--out",
        c.path("OUT.blend"),
        "--target",
        "image",
        "--image-size",
        "64",
        "--samples",
        "2",
    )
    images = c.path("OUT_thickness")
    files = sorted(n for n in os.listdir(images) if n.endswith(".exr")) if os.path.isdir(images) else []
    if run.code == 2:
        return handled(run.brief())
    saved = [ln for ln in run.out.splitlines() if ln.startswith("Saved:") and ln.rstrip("'").endswith(".exr")]
    if run.code == 0 and len(files) == 2 and len(set(saved)) == len(saved) == 2:
        return handled(f"two images: {files}")
    return not_handled(f"{run.brief()}; images {files}; Saved lines {[clip(s, 80) for s in saved]}")


@case("bl28_render_border", "BLEND", "render with a render border and Crop to Border, then apply")
def bl28(c: Ctx) -> Verdict:
    out = c.path("o")
    run = _render(c, c.work.blend("render_border"), out)
    if run.code != 0:
        return judge(refused(run, 2, [("border", "crop")]), run.brief())
    applied = c.sss("apply", os.path.join(out, "passes_0001.exr"), "--methods", "all")
    if applied.code == 0:
        return handled("rendered and applied")
    w, h = exr_size(os.path.join(out, "passes_0001.exr"))
    camera = json.load(open(os.path.join(out, "passes_0001.json"))).get("camera", {})
    wrote = f"render exit 0 wrote a {w}x{h} EXR beside a JSON of {camera.get('width_px')}x{camera.get('height_px')}"
    reason = lines_with(applied.err, "error")
    return not_handled(f"{wrote}; apply exit {applied.code}: ...{clip(reason[0][-90:] if reason else applied.said())}")


@case("bl36_gn_material_scan", "BLEND", "scan: the SSS material set by a Geometry Nodes Set Material node")
def bl36(c: Ctx) -> Verdict:
    run = c.sss("scan", c.work.blend("gn_material"))
    if _scan_lists(run) or lines_with(run.text, ("geometry nodes", "set material", "modifier")):
        return handled("the material listed" if _scan_lists(run) else "said")
    return not_handled(f"the material is not listed, nothing said of Geometry Nodes; {run.brief()}")


@case("bl37_gn_material_render", "BLEND", "render: the SSS material set by Geometry Nodes")
def bl37(c: Ctx) -> Verdict:
    return _render_lists(c, c.work.blend("gn_material"), "geometry nodes", "set material", "modifier")[1]


@case("bl46_driver_weight_scan", "BLEND", "scan: Subsurface Weight driven by an expression that may not run")
def bl46(c: Ctx) -> Verdict:
    run = c.sss("scan", c.work.blend("driver_weight"))
    said = lines_with(run.text, "driver")
    if run.code == 0 and said:
        what = lines_with(run.text, "driver", ("weight", "skin"))
        where = "" if what else " (the driver named, not the socket it drives)"
        return handled(f"said: {clip(said[0], 140)}{where}")
    return not_handled(f"no word of the driver; {run.brief()}")


# CLI ---------------------------------------------------------------------------------------


@case("cl09_param_twice", "CLI", "apply --param n_samples given twice")
def cl09(c: Ctx) -> Verdict:
    exr = c.passes()
    run = c.sss(
        "apply",
        exr,
        "--methods",
        "burley",
        "--out",
        c.path("o.exr"),
        "--param",
        "n_samples=16",
        "--param",
        "n_samples=8",
    )
    if run.code == 0 and lines_with(run.text, "n_samples", ("twice", "more than once", "again", "last")):
        return handled("the last kept, said")
    return judge(refused(run, 2, ["n_samples"]), run.brief())


@case("cl16_out_empty", "CLI", "apply --out ''")
def cl16(c: Ctx) -> Verdict:
    exr = c.passes()
    run = c.sss("apply", exr, "--methods", "burley", "--out", "")
    default = exr[:-4] + ".sss.exr"
    return judge(refused(run, 2, ["--out"]) or (os.path.exists(default) and "the default output written"), run.brief())


@case("cl27_resolution_65536", "CLI", "render --resolution 65536x65536 with 6 GB of address space")
def cl27(c: Ctx) -> Verdict:
    run = c.sss(
        "render",
        c.work.scene(),
        "--out",
        c.path("o"),
        "--resolution",
        "65536x65536",
        "--pass-samples",
        "1",
        limit_as=6_000_000 * 1024,
        timeout=180,
        note="under ulimit -v 6000000",
    )
    if run.timed_out:
        return not_handled(f"no result within {run.seconds:.0f} s")
    return judge(refused(run, 2, ["65536"]) if run.code != 1 else refused(run, 1, ["65536"]), run.brief())


@case("cl42_cmp_cache_file", "CLI", "compare --cache naming an existing file")
def cl42(c: Ctx) -> Verdict:
    afile = c.path("afile")
    open(afile, "w").write("not a folder\n")
    run = c.sss(
        "compare",
        c.work.scene(),
        "--out",
        c.path("o"),
        "--cache",
        afile,
        "--resolution",
        "32x32",
        "--reference-samples",
        "2",
        "--pass-samples",
        "2",
        "--bias-samples",
        "0",
        *FAST_COMPARE,
        inputs=[afile],
    )
    problem = refused(run, 2, ["--cache", ("folder", "directory")])
    if "rendering" in run.out:
        problem = (problem + "; " if problem else "") + "it rendered before it stopped"
    return judge(problem, run.brief())


@case("cl50_cal_methods_empty", "CLI", "calibrate --methods ''")
def cl50(c: Ctx) -> Verdict:
    run = c.sss(
        "calibrate",
        c.work.scene(),
        "--out",
        c.path("o.blend"),
        "--resolution",
        "32x32",
        "--samples",
        "2",
        "--methods",
        "",
    )
    return judge(refused(run, 2, ["--methods"], absent=["techniques:"]), run.brief())


@case("cl53_cal_max_samples_below", "CLI", "calibrate --samples 8 --max-samples 2")
def cl53(c: Ctx) -> Verdict:
    run = c.sss(
        "calibrate",
        c.work.scene(),
        "--out",
        c.path("o.blend"),
        "--resolution",
        "32x32",
        "--samples",
        "8",
        "--max-samples",
        "2",
    )
    return judge(refused(run, 2, ["--max-samples"], absent=["max_samples:"]), run.brief())


@case("cl55_bake_image_size_huge", "CLI", "bake-thickness --target image --image-size 100000")
def cl55(c: Ctx) -> Verdict:
    run = c.sss(
        "bake-thickness",
        c.work.blend("head_uv"),
        "--out",
        c.path("o.blend"),
        "--target",
        "image",
        "--image-size",
        "100000",
        "--samples",
        "1",
        limit_as=6_000_000 * 1024,
        note="under ulimit -v 6000000",
    )
    return judge(refused(run, 2, ["--image-size"], absent=["resolution_px"]), run.brief())


@case("cl63_scan_maxerror_neg", "CLI", "scan --recommend --max-error -1")
def cl63(c: Ctx) -> Verdict:
    run = c.sss("scan", c.work.scene(), "--recommend", "--max-error", "-1", "--resolution", "32x32", "--samples", "2")
    return judge(refused(run, 2, ["--max-error"], absent=["max_error:"]), run.brief())


@case("cl66_demo_out_file", "CLI", "demo --out naming an existing file")
def cl66(c: Ctx) -> Verdict:
    afile = c.path("afile")
    open(afile, "w").write("a file\n")
    run = c.sss("demo", "--out", afile, "--pass-samples", "1", "--reference-samples", "1", inputs=[afile])
    return judge(refused(run, 2, ["afile"], absent=["afile/"]), run.brief())


# INT ---------------------------------------------------------------------------------------


def _stopped(run: Run, name: str) -> str | None:
    if not run.signalled:
        return f"the command ended before the signal ({run.brief()}): nothing interrupted"
    problems = []
    if run.code != 130:
        problems.append(f"exit {run.code}, expected 130")
    if run.stopped is not None and run.stopped > STOP_WITHIN:
        problems.append(f"stopped {run.stopped:.1f} s after {name}")
    if problems:
        return "; ".join(problems) + f" ({clip(run.said())})"
    return None


def _int_note(run: Run) -> str:
    return f"exit 130, {run.stopped:.1f} s after the signal"


@case("in03_render_sighup", "INT", "SIGHUP to render during frame 2 of 3")
def in03(c: Ctx) -> Verdict:
    out = c.path("o")
    run = c.sss_signal(
        "render",
        c.work.scene(),
        "--out",
        out,
        "--frames",
        "1-3",
        "--resolution",
        "48x48",
        "--pass-samples",
        "2000",
        "--methods",
        "ssss,burley",
        signum=signal.SIGHUP,
        when_line="frame 1 done",
        after=0.2,
    )
    problem = _stopped(run, "SIGHUP")
    if problem:
        return not_handled(problem)
    files = sorted(os.listdir(out))
    whole = exr_problem(os.path.join(out, "passes_0001.exr"))
    if files != ["passes_0001.exr", "passes_0001.json"] or whole:
        return not_handled(f"frames left: {files}" + (f"; frame 1 {whole}" if whole else ""))
    return handled(_int_note(run) + ", frame 1 kept whole")


def _calibrate_interrupted(c: Ctx, signum: int) -> Verdict:
    out = c.path("OUT.blend")
    run = c.sss_signal(
        "calibrate",
        c.work.backlit(),
        "--out",
        out,
        "--resolution",
        "48x48",
        "--samples",
        "20000",
        "--pass-samples",
        "16",
        signum=signum,
        when_line="Cycles random walk",
        after=1.5,
    )
    problem = _stopped(run, signal.Signals(signum).name)
    if problem:
        return not_handled(problem)
    if os.path.exists(out):
        return not_handled("OUT.blend written by an interrupted calibrate")
    claim = ", says 'no partial file left'" if "no partial file left" in run.err else ""
    return handled(_int_note(run) + claim)


@case("in06_calibrate_sigint", "INT", "Ctrl-C to calibrate during its Cycles render")
def in06(c: Ctx) -> Verdict:
    return _calibrate_interrupted(c, signal.SIGINT)


@case("in07_calibrate_sigterm", "INT", "SIGTERM to calibrate during its Cycles render")
def in07(c: Ctx) -> Verdict:
    return _calibrate_interrupted(c, signal.SIGTERM)


@case("in09_reference_sigterm", "INT", "SIGTERM to reference --seeds 1-3 after part 1 is saved")
def in09(c: Ctx) -> Verdict:
    out = c.path("P")
    run = c.sss_signal(
        "reference",
        c.work.scene(),
        "--out",
        out,
        "--seeds",
        "1-3",
        "--samples",
        "1500",
        "--resolution",
        "48x48",
        signum=signal.SIGTERM,
        when_line="seed 1 done",
        after=0.5,
    )
    problem = _stopped(run, "SIGTERM")
    if problem:
        return not_handled(problem)
    files = sorted(os.listdir(out))
    whole = exr_problem(os.path.join(out, "reference_seed_00001.exr"))
    if files != ["reference_seed_00001.exr", "reference_seed_00001.json"] or whole:
        return not_handled(f"parts left: {files}" + (f"; part 1 {whole}" if whole else ""))
    return handled(_int_note(run) + ", part 1 kept whole")


@case("in15_compare_sigterm_rerun", "INT", "SIGTERM to compare during its reference render, then compare again")
def in15(c: Ctx) -> Verdict:
    args = [
        "compare",
        c.work.scene(),
        "--out",
        c.path("o"),
        "--resolution",
        "48x48",
        "--reference-samples",
        "600",
        "--pass-samples",
        "4",
        "--bias-samples",
        "0",
        *FAST_COMPARE,
    ]
    run = c.sss_signal(*args, signum=signal.SIGTERM, when_line="rendering", after=1.0)
    problem = _stopped(run, "SIGTERM")
    if problem:
        return not_handled(problem)
    left = leftovers(c.dir)
    if left:
        return not_handled(f"left after SIGTERM: {left}")
    again = c.sss(*args)
    return judge(None if again.code == 0 else f"the rerun: {again.brief()}", _int_note(run) + ", the rerun complete")


@case("in17_prepare_sigint", "INT", "Ctrl-C to prepare while it compiles into an empty kernel cache")
def in17(c: Ctx) -> Verdict:
    cache = c.path("numba_cache")
    os.makedirs(cache)
    run = c.sss_signal(
        "prepare", signum=signal.SIGINT, when_line="compiling", after=1.5, env={"NUMBA_CACHE_DIR": cache}
    )
    return judge(_stopped(run, "Ctrl-C"), _int_note(run) if run.stopped is not None else "")


# EXRV --------------------------------------------------------------------------------------


def _huge(c: Ctx, pass_name: str, value: float) -> Verdict:
    d = description_of(c)

    def set_on_skin(parts):
        mask = skin_mask(parts, d)
        for _, channels in parts:
            for key in list(channels):
                if key.startswith(f"ViewLayer.{pass_name}.") and key[-1] in "RGB":
                    channels[key] = np.where(mask, np.float32(value), channels[key]).astype(np.float32)

    exr = c.passes(exr=set_on_skin)
    out = c.path("out.exr")
    run = c.sss("apply", exr, "--methods", "all", "--out", out)
    if run.code == 2:
        return handled(run.brief())
    if run.code != 0:
        return not_handled(run.brief())
    negative, nonfinite = {}, {}
    for name, img in image_layers(out).items():
        with np.errstate(invalid="ignore"):
            n = int(np.sum(img < 0))
        if n:
            negative[name] = f"{n} (min {np.nanmin(img):.3g})"
        m = int(np.sum(~np.isfinite(img)))
        if m:
            nonfinite[name] = m
    if negative:
        return not_handled(f"exit 0 with negative pixels: {negative}")
    if nonfinite and not lines_with(run.text, ("overflow", "float32", "infinite", "inf")):
        return not_handled(f"exit 0 with non-finite pixels and no word of them: {nonfinite}")
    return handled("exit 0, no negative pixel" + (f"; non-finite pixels said: {nonfinite}" if nonfinite else ""))


@case("ev17_dd_huge", "EXRV", "apply with Diffuse Direct 3e38 on the skin")
def ev17(c: Ctx) -> Verdict:
    return _huge(c, "Diffuse Direct", 3e38)


@case("ev20_dc_huge", "EXRV", "apply with Diffuse Color 1e30 on the skin")
def ev20(c: Ctx) -> Verdict:
    return _huge(c, "Diffuse Color", 1e30)


@case("ev35_dd_extra_alpha", "EXRV", "apply with an extra A channel in Diffuse Direct")
def ev35(c: Ctx) -> Verdict:
    def add_alpha(parts):
        for _, channels in parts:
            if "ViewLayer.Diffuse Direct.R" in channels:
                channels["ViewLayer.Diffuse Direct.A"] = np.ones_like(channels["ViewLayer.Diffuse Direct.R"])

    exr = c.passes(exr=add_alpha)
    out = c.path("out.exr")
    run = c.sss("apply", exr, "--methods", "all", "--out", out)
    if run.code == 0:
        layers = sorted(image_layers(out))
        return judge(None if len(layers) == 4 else f"exit 0 but only {layers}", "complete result, A ignored")
    return judge(refused(run, 2, ["Diffuse Direct"], absent=["broadcast"]), run.brief())


# MAT ---------------------------------------------------------------------------------------


def _zero(c: Ctx, key: str, value, word: str) -> Verdict:
    exr = c.passes(desc=lambda d: d["materials"][0].update({key: value}))
    out = c.path("out.exr")
    run = c.sss("apply", exr, "--methods", "all", "--out", out)
    if run.code == 0:
        bad = {k: int(np.sum(~np.isfinite(v) | (v < 0))) for k, v in image_layers(out).items()}
        bad = {k: v for k, v in bad.items() if v}
        return judge(bad and f"exit 0 with negative or non-finite pixels: {bad}", "complete, finite result")
    said = lines_with(run.text, "skin", word)
    if run.code in (2, 3) and said and "Traceback" not in run.text:
        return handled(f"exit {run.code}: {clip(said[0], 140)}")
    return not_handled(f"the message does not name the {word}; {run.brief()}")


@case("ma01_radius_zero", "MAT", "apply with subsurface_radius (0, 0, 0)")
def ma01(c: Ctx) -> Verdict:
    return _zero(c, "subsurface_radius", [0.0, 0.0, 0.0], "radius")


@case("ma06_scale_zero", "MAT", "apply with subsurface_scale 0")
def ma06(c: Ctx) -> Verdict:
    return _zero(c, "subsurface_scale", 0.0, "scale")


# UNIT --------------------------------------------------------------------------------------


def _scaled_scene(c: Ctx, k: float) -> Verdict:
    """The scene's own passes and description with every length times ``k`` (Depth, Position,
    camera and lights, light sizes, Subsurface Scale, the thickness distance; area light energy
    times k**2, a sun's irradiance unchanged), so that what the passes hold is the same picture
    at another unit scale with no render noise between them; apply on both."""

    def exr(parts):
        for _, channels in parts:
            for key in channels:
                if key.startswith(("ViewLayer.Depth.", "ViewLayer.Position.")):
                    channels[key] = (channels[key].astype(np.float64) * k).astype(np.float32)

    def desc(d):
        cam = d["camera"]
        for i in (3, 7, 11):
            cam["matrix_world"][i] *= k
        for key in ("clip_start", "clip_end", "ortho_scale"):
            cam[key] *= k
        for light in d["lights"]:
            for i in (3, 7, 11):
                light["matrix_world"][i] *= k
            for key in ("size", "size_y", "radius"):
                light[key] *= k
            if light["type"] != "SUN":
                light["energy"] *= k * k
        for m in d["materials"]:
            m["subsurface_scale"] *= k
            if m.get("thickness_distance"):
                m["thickness_distance"] *= k

    metre = c.passes(name="m/passes_0001")
    scaled = c.passes(exr=exr, desc=desc, name="k/passes_0001")
    runs = [c.sss("apply", p, "--methods", "all", "--out", p[:-4] + ".sss.exr") for p in (metre, scaled)]
    for run in runs:
        if run.code != 0:
            return not_handled(run.brief())
    a, b = (sss_layers(p[:-4] + ".sss.exr") for p in (metre, scaled))
    rel = {t: float(np.abs(a[t] - b[t]).sum() / max(np.abs(a[t]).sum(), 1e-30)) for t in sorted(a) if t in b}
    shown = ", ".join(f"{t} {v:.2g}" for t, v in rel.items())
    return judge(
        max(rel.values()) > 1e-3 and f"the SSS term changes (relative L1 against the metre scene: {shown})",
        f"SSS term unchanged (relative L1: {shown})",
    )


@case("un03_scene_x1000", "UNIT", "the scene 1000 times larger: the SSS term of every technique")
def un03(c: Ctx) -> Verdict:
    return _scaled_scene(c, 1000.0)


@case("un04_scene_x0001", "UNIT", "the scene 1000 times smaller: the SSS term of every technique")
def un04(c: Ctx) -> Verdict:
    return _scaled_scene(c, 0.001)


# SCENE -------------------------------------------------------------------------------------


@case("sc_camera_away_compare", "SCENE", "compare with the camera turned away from every subsurface material")
def sc_camera_away(c: Ctx) -> Verdict:
    run = c.sss(
        "compare",
        c.work.blend("camera_away"),
        "--out",
        c.path("o"),
        "--resolution",
        "32x32",
        "--reference-samples",
        "2",
        "--pass-samples",
        "2",
        "--bias-samples",
        "0",
        *FAST_COMPARE,
    )
    said = lines_with(run.text, "screen")
    if run.code != 0 and said:
        return handled(f"exit {run.code}: {clip(said[0], 140)}")
    if run.code == 0 and said:
        return handled(f"exit 0, said: {clip(said[0], 140)}")
    return not_handled(f"no line says nothing subsurface is on screen; {run.brief()}")


# CLI4 --------------------------------------------------------------------------------------


@case("ci07_method_all_plus", "CLI4", "apply --methods all,sta")
def ci07(c: Ctx) -> Verdict:
    exr = c.passes()
    run = c.sss("apply", exr, "--methods", "all,sta", "--out", c.path("o.exr"))
    if run.code == 0:
        return handled("ran")
    return judge(refused(run, 2, ["all"], absent=["unknown method 'all'"]), run.brief())


@case("ci30_frames_empty", "CLI4", "apply --frames ''")
def ci30(c: Ctx) -> Verdict:
    exr = c.passes()
    run = c.sss("apply", exr, "--methods", "burley", "--out", c.path("o.exr"), "--frames", "")
    return judge(refused(run, 2, ["--frames"]) or (os.path.exists(c.path("o.exr")) and "o.exr written"), run.brief())


# CACHE -------------------------------------------------------------------------------------


def _cached_compare(c: Ctx, damage: Callable[[str, str], None]) -> Verdict:
    fx = c.work.fixture("cache")
    cache = c.path("cache")
    shutil.copytree(fx["dir"], cache)
    entry = fx["entry"]
    damage(cache, entry)
    run = c.sss("compare", c.work.scene(), "--out", c.path("o"), "--cache", cache, *CACHE_COMPARE, *FAST_COMPARE)
    if run.code != 0:
        if run.code == 2 and entry in run.err:
            return handled(run.brief())
        return not_handled(run.brief())
    reused = f"cached ({entry}.exr)" in run.out
    noted = lines_with(run.text, entry)
    if reused:
        return not_handled("the damaged entry reused" + (f" ({clip(noted[0], 120)})" if noted else ", no note"))
    if not noted:
        return not_handled("rendered again without a note naming the entry")
    return handled(f"rendered again with a note: {clip(noted[0], 140)}")


def _meta(field_value):
    def damage(cache, entry):
        path = os.path.join(cache, entry + ".json")
        data = json.load(open(path))
        data.update(field_value)
        json.dump(data, open(path, "w"))

    return damage


def _pixels(value):
    def damage(cache, entry):
        path = os.path.join(cache, entry + ".exr")
        parts = exr_read(path)
        for _, channels in parts:
            for key in channels:
                channels[key] = np.full_like(channels[key], value)
        exr_write(path, parts)

    return damage


@case("ca01_seconds_negative", "CACHE", "compare whose cached reference says it took -5 s")
def ca01(c: Ctx) -> Verdict:
    return _cached_compare(c, _meta({"seconds": -5}))


@case("ca02_seconds_1e308", "CACHE", "compare whose cached reference says it took 1e308 s")
def ca02(c: Ctx) -> Verdict:
    return _cached_compare(c, _meta({"seconds": 1e308}))


@case("ca06_exr_nan", "CACHE", "compare whose cached reference is all NaN (same size)")
def ca06(c: Ctx) -> Verdict:
    return _cached_compare(c, _pixels(np.nan))


@case("ca09_exr_inf", "CACHE", "compare whose cached reference is all Inf")
def ca09(c: Ctx) -> Verdict:
    return _cached_compare(c, _pixels(np.inf))


@case("cm01_ref_samples_1e9", "CACHE", "compare --reference whose JSON says 1e9 samples")
def cm01(c: Ctx) -> Verdict:
    run = _compare_reference(c, c.ref(edit=lambda d: d.update(samples=1_000_000_000)))
    return judge(_accepted(run, refused(run, 2, ["ref.json", "samples"])), run.brief())


@case("cm02_ref_samples_negative", "CACHE", "compare --reference whose JSON says -8 samples")
def cm02(c: Ctx) -> Verdict:
    run = _compare_reference(c, c.ref(edit=lambda d: d.update(samples=-8)))
    return judge(refused(run, 2, ["ref.json", "samples"]), run.brief())


@case("cm03_ref_resolution_edited", "CACHE", "compare --reference whose JSON says 32x32 for a 48x48 EXR")
def cm03(c: Ctx) -> Verdict:
    run = _compare_reference(c, c.ref(edit=lambda d: d.update(resolution=[32, 32])))
    return judge(_accepted(run, refused(run, 2, ["ref.json", "resolution"])), run.brief())


# VERIFY ------------------------------------------------------------------------------------

FIT = ["--resolution", "64x64", "--samples", "16", "--pass-samples", "8"]


@case("vr01_calibrate_json_is_input_fit", "VERIFY", "calibrate --json naming the input .blend, on a fit that succeeds")
def vr01(c: Ctx) -> Verdict:
    blend = c.path("IN.blend")
    shutil.copyfile(c.work.scene(), blend)
    run = c.sss("calibrate", blend, "--out", c.path("OUT.blend"), *FIT, "--json", blend, inputs=[blend])
    if run.changed:
        return not_handled(f"the input changed; {run.brief()}")
    return judge(
        refused(run, 2, ["IN.blend"]) or (os.path.exists(c.path("OUT.blend")) and "OUT.blend written"), run.brief()
    )


@case("vr02_calibrate_json_is_out_fit", "VERIFY", "calibrate --json naming --out, on a fit that succeeds")
def vr02(c: Ctx) -> Verdict:
    out = c.path("OUT.blend")
    run = c.sss("calibrate", c.work.scene(), "--out", out, "--json", out, *FIT)
    if os.path.exists(out) and not is_blend(out):
        return not_handled(f"OUT.blend is not a .blend (the JSON took its place); {run.brief()}")
    return judge(refused(run, 2, ["OUT.blend"]), run.brief())


@case("vr04_two_calibrates_same_out", "VERIFY", "two calibrate to one --out started together")
def vr04(c: Ctx) -> Verdict:
    out = c.path("OUT.blend")
    cmd = ["calibrate", c.work.scene(), "--out", out, *FIT]
    return _two_writers(c, c.together(cmd, cmd), out)


def _full_blend(c: Ctx, size: str, *args) -> Verdict:
    full = c.path("disk")
    run = c.sss_on_disks(*args, "--out", os.path.join(full, "o.blend"), disks={full: f"size={size}"})
    if run is None:
        return not_run(f"no tmpfs can be mounted here ({c.work.mount_reason})")
    return judge(_blend_left(c, full + ".after", run), run.brief())


@case("vr05_bake_full_disk", "VERIFY", "bake-thickness --out on a full 64 KB disk, then open what it wrote")
def vr05(c: Ctx) -> Verdict:
    return _full_blend(c, "64k", "bake-thickness", c.work.scene(), "--samples", "4")


@case("vr06_bake_full_disk_16k", "VERIFY", "bake-thickness --out on a full 16 KB disk, then open what it wrote")
def vr06(c: Ctx) -> Verdict:
    return _full_blend(c, "16k", "bake-thickness", c.work.scene(), "--samples", "4")


@case("vr07_calibrate_full_disk", "VERIFY", "calibrate --out on a full 64 KB disk, then open what it wrote")
def vr07(c: Ctx) -> Verdict:
    return _full_blend(c, "64k", "calibrate", c.work.scene(), *FIT)


# KILL --------------------------------------------------------------------------------------


def _hidden_beside(folder: str, name: str) -> Callable[[], bool]:
    def seen() -> bool:
        try:
            return any(n.startswith("." + name) for n in os.listdir(folder))
        except FileNotFoundError:
            return False

    return seen


@case("ik02_apply_sigkill_late", "KILL", "SIGKILL to apply once its temporary output exists, then --skip-existing")
def ik02(c: Ctx) -> Verdict:
    d = description_of(c)
    for scale in (8, 16):

        def bigger(parts, s=scale):
            for _, channels in parts:
                for key in channels:
                    channels[key] = np.repeat(np.repeat(channels[key], s, axis=0), s, axis=1)

        def sized(desc, s=scale):
            desc["camera"]["width_px"] = d["camera"]["width_px"] * s
            desc["camera"]["height_px"] = d["camera"]["height_px"] * s

        exr = c.passes(exr=bigger, desc=sized, name=f"x{scale}/passes_0001")
        out = os.path.join(os.path.dirname(exr), "out.exr")
        run = c.sss_signal(
            "apply",
            exr,
            "--methods",
            "sta",
            "--out",
            out,
            signum=signal.SIGKILL,
            when=_hidden_beside(os.path.dirname(out), "out.exr"),
            when_shown="a hidden temporary of out.exr appears",
            poll=0.001,
        )
        if run.signalled:
            break
    else:
        return not_run("apply ended before its temporary output was seen, twice (the write is too quick to catch here)")
    if os.path.exists(out):
        return not_handled("a file under the output's name after SIGKILL")
    again = c.sss("apply", exr, "--methods", "sta", "--out", out, "--skip-existing")
    if again.code != 0 or exr_problem(out):
        return not_handled(f"the rerun: {again.brief()}; out.exr {exr_problem(out) or 'whole'}")
    return handled(f"killed while writing a {48 * scale}x{48 * scale} output; the rerun wrote it whole")


@case("ik03_reference_sigkill", "KILL", "SIGKILL to reference --seeds 1-2 while it writes part 1, then --skip-existing")
def ik03(c: Ctx) -> Verdict:
    out = c.path("P")
    args = ["reference", c.work.scene(), "--out", out, "--seeds", "1-2", "--samples", "600", "--resolution", "48x48"]
    run = c.sss_signal(
        *args,
        signum=signal.SIGKILL,
        when=_hidden_beside(out, "reference_seed_00001"),
        when_shown="a hidden temporary of part 1 appears",
        poll=0.001,
    )
    if not run.signalled:
        return not_run("reference ended before a temporary of part 1 was seen")
    again = c.sss(*args, "--skip-existing")
    if again.code != 0:
        return not_handled(f"the rerun: {again.brief()}")
    for seed in (1, 2):
        problem = exr_problem(os.path.join(out, f"reference_seed_{seed:05d}.exr"))
        if problem:
            return not_handled(f"part {seed} {problem} after the rerun")
    return handled("the rerun wrote both parts")


# --------------------------------------------------------------------------------------------
# Running and reporting


def run_case(work: Work, case_: Case) -> dict:
    start = time.perf_counter()
    c = Ctx(work, case_.id, CASES.index(case_))
    try:
        v = case_.run(c)
    except FixtureError as exc:
        v = not_run(f"a fixture could not be made: {exc}")
    except Exception as exc:  # noqa: BLE001 - a fault of this harness, reported as such
        import traceback

        traceback.print_exc()
        v = not_run(f"the harness failed on this case: {type(exc).__name__}: {exc}")
    if v.status == HANDLED:
        problems = []
        for run in c.runs:
            if run.timed_out:
                problems.append(f"no result within {run.seconds:.0f} s: {run.shown}")
            if "Traceback (most recent call last)" in run.text:
                problems.append(f"a traceback ({clip(run.said(), 120)})")
            if run.changed:
                problems.append(f"inputs changed: {run.changed}")
        left = leftovers(c.dir)
        if left:
            problems.append(f"left behind: {left}")
        if problems:
            v = not_handled((f"{v.reason}; but " if v.reason else "") + "; ".join(problems))
    return {
        "id": case_.id,
        "class": case_.cls,
        "what": case_.what,
        "verdict": v.status,
        "reason": visible(work.show(v.reason)),
        "commands": [visible(r.shown) for r in c.runs],
        "exits": [r.code for r in c.runs],
        "seconds": round(time.perf_counter() - start, 2),
    }


def class_table(records: list[dict]) -> str:
    lines = [
        "| class | what its cases do | tried | handled | not handled | not run here |",
        "|---|---|---|---|---|---|",
    ]
    totals = [0, 0, 0, 0]
    for cls, what in CLASSES.items():
        mine = [r for r in records if r["class"] == cls]
        if not mine:
            continue
        h = sum(r["verdict"] == HANDLED for r in mine)
        n = sum(r["verdict"] == NOT_HANDLED for r in mine)
        s = sum(r["verdict"] == NOT_RUN for r in mine)
        for i, v in enumerate((h + n, h, n, s)):
            totals[i] += v
        lines.append(f"| {cls} | {what} | {h + n} | {h} | {n} | {s} |")
    lines.append(f"| **total** | | **{totals[0]}** | **{totals[1]}** | **{totals[2]}** | **{totals[3]}** |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="", help="comma-separated classes: " + ", ".join(CLASSES))
    parser.add_argument("--ids", default="", help="comma-separated case ids (see --list); with --only: both sets")
    parser.add_argument("--json", default=None, help="write every case's record (commands, exits, verdict) here")
    parser.add_argument(
        "--table",
        action="store_true",
        help="also print the cases not handled and not run here as Markdown, with the date",
    )
    parser.add_argument("--list", action="store_true", help="list the cases and stop")
    parser.add_argument("--keep", action="store_true", help="keep the work folder (its path is printed)")
    args = parser.parse_args(argv)
    only = {s.strip().upper() for s in args.only.split(",") if s.strip()}
    ids = {s.strip() for s in args.ids.split(",") if s.strip()}
    unknown = (only - set(CLASSES)) | (ids - {c.id for c in CASES})
    if unknown:
        parser.error(f"unknown class or case: {', '.join(sorted(unknown))}")
    chosen = [c for c in CASES if (not only and not ids) or c.cls in only or c.id in ids]
    if args.list:
        for c in chosen:
            print(f"{c.id:<36} {c.cls:<7} {c.what}")
        return 0
    which = subprocess.run([PYTHON, "-c", "import sss_lab; print(sss_lab.__file__)"], capture_output=True, text=True)
    package = os.path.dirname(which.stdout.strip())
    if os.path.realpath(package) != os.path.realpath(ROOT):
        print(f"warning: `python -m sss_lab` runs {package or which.stderr.strip()}, not {ROOT}", file=sys.stderr)
    root = tempfile.mkdtemp(prefix="sss_cli_cases_")
    work = Work(root)
    print(f"{len(chosen)} case(s); work folder {root}", flush=True)
    start = time.perf_counter()
    records = []
    try:
        for case_ in chosen:
            record = run_case(work, case_)
            records.append(record)
            print(
                f"{record['id']:<36} {record['verdict']:<12} {record['seconds']:6.1f} s  {record['reason']}", flush=True
            )
    finally:
        seconds = time.perf_counter() - start
        if args.keep:
            print(f"work folder kept: {root}")
        else:
            shutil.rmtree(root, ignore_errors=True)
    table = class_table(records)
    print()
    print(table)
    print(f"\n{len(records)} case(s) in {seconds / 60:.1f} min")
    if args.table:
        print(f"\nRun on {datetime.date.today().isoformat()} ({seconds / 60:.1f} min).\n")
        for status in (NOT_HANDLED, NOT_RUN):
            mine = [r for r in records if r["verdict"] == status]
            print(f"Cases {status}: " + ("none." if not mine else ""))
            for r in mine:
                print(f"- `{r['id']}` ({r['what']}): {r['reason']}")
            print()
    if args.json:
        data = {"date": datetime.date.today().isoformat(), "seconds": round(seconds, 1), "cases": records}
        with open(args.json, "w") as f:
            json.dump(data, f, indent=2)
        print(f"Saved: '{args.json}'")
    return 0 if all(r["verdict"] != NOT_HANDLED for r in records) else 1


if __name__ == "__main__":
    sys.exit(main())
