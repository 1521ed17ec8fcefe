"""The import graph of the source tree (every tracked .py file outside tests/), read with ``ast``:
no import cycle, no import upward across the layers, no private name of another module.

Every ``import`` and ``from ... import`` counts, relative or absolute, also inside a function.
"""

import ast
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "sss_lab"

#: Layers of top-level folders, highest first: a module imports its own layer's and lower ones'.
LAYERS = (("__init__", "__main__"), ("addon",), ("operators",), ("nodes", "blender"), ("core",))
#: Folders beside the layers: they may import anything but these.
TOOLS = {f: {"addon", "operators"} for f in ("benchmarks", "tools", "sample_blends", "farm")}
#: What a tool may import of those all the same: the command line's entry point, which the
#: reliability benchmark runs in-process to put faults under it (not a library of helpers).
ENTRY_POINTS = {"addon/cli.py"}
#: The subpackages of core, lowest first: each imports its own and lower ones only.
CORE_LAYERS = (
    "core.base",
    "core.compute",
    "core.scene",
    "core.optics",
    "core.techniques",
    "core.pipeline",
    "core.study",
)
#: (importer, imported) dotted prefixes that may not import each other, beyond the layers.
RULES: list[tuple[str, str]] = [(low, high) for i, low in enumerate(CORE_LAYERS) for high in CORE_LAYERS[i + 1 :]]
#: A technique folder imports no other technique folder, but those it is made of: the combined
#: technique is Burley's or SSSS's diffusion plus its own light from behind (its spec takes their
#: parameters). A declared composition, not an allow-list.
COMPOSES = {"combined": {"burley", "ssss"}}
#: What ``core`` never imports (it runs without Blender).
NOT_IN_CORE = {"bpy", "bmesh", "mathutils", "gpu", "bl_math", "idprop"}


def _sources() -> list[str]:
    try:
        out = subprocess.run(["git", "ls-files", "*.py"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
        files = out.split()
    except (OSError, subprocess.CalledProcessError):  # not a git checkout: every .py file
        files = [p.relative_to(ROOT).as_posix() for p in ROOT.rglob("*.py") if ".venv" not in p.parts]
    return sorted(f for f in files if not f.startswith("tests/") and (ROOT / f).is_file())


def _module_file(parts: list[str]) -> str | None:
    """The file of module ``parts`` of the tree (a .py file or a package's __init__.py), or None."""
    for cand in (["/".join(parts) + ".py"] if parts else []) + ["/".join([*parts, "__init__.py"])]:
        if (ROOT / cand).is_file():
            return cand
    return None


def _dotted(path: str) -> str:
    return path.removesuffix(".py").removesuffix("/__init__").replace("/", ".")


def _scan(path: str):
    """(imported files, external top-level names, private reads as "module.name") of ``path``."""
    tree = ast.parse((ROOT / path).read_text(encoding="utf-8"), path)
    package = path.split("/")[:-1]
    edges, external, private, aliases = set(), set(), set(), {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                if parts[0] != PACKAGE:
                    external.add(parts[0])
                elif target := _module_file(parts[1:]):
                    edges.add(target)
                    if a.asname:
                        aliases[a.asname] = target
        elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
            parts = (node.module or "").split(".") if node.module else []
            if node.level:
                base = package[: len(package) - node.level + 1] + parts
            elif parts[0] == PACKAGE:
                base = parts[1:]
            else:
                external.add(parts[0])
                continue
            for a in node.names:
                if sub := _module_file([*base, a.name]):  # a module of the package
                    edges.add(sub)
                    aliases[a.asname or a.name] = sub
                    if a.name.startswith("_") and base != package:
                        private.add(f"{_dotted(sub)}")
                elif target := _module_file(base):
                    edges.add(target)
                    if a.name.startswith("_") and not a.name.startswith("__"):
                        private.add(f"{_dotted(target)}.{a.name}")
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            if node.attr.startswith("_") and not node.attr.startswith("__"):
                private.add(f"{_dotted(aliases[node.value.id])}.{node.attr}")
    edges.discard(path)
    return edges, external, private


GRAPH = {f: _scan(f) for f in _sources()}


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one file (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def _layer(path: str) -> str:
    return path.split("/")[0].removesuffix(".py")


def _upward(importer: str, imported: str) -> str | None:
    """Why ``importer`` may not import ``imported``, or None."""
    a, b = _layer(importer), _layer(imported)
    rank = {name: i for i, names in enumerate(LAYERS) for name in names}
    if a in TOOLS:
        return f"{a} may not import {b}" if b in TOOLS[a] and imported not in ENTRY_POINTS else None
    if b in TOOLS or (a in rank and b in rank and rank[b] < rank[a]):
        return f"{a} is below {b}"
    for low, high in RULES:
        if _dotted(importer).startswith(low) and _dotted(imported).startswith(high):
            return f"{low} may not import {high}"
    return None


def test_no_import_cycle():
    cycles = _cycles({f: set(e) for f, (e, _, _) in GRAPH.items()})
    assert not cycles, "import cycles among source files:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_no_import_upward_across_the_layers():
    found = {(f, t): why for f, (e, _, _) in GRAPH.items() for t in e if (why := _upward(f, t))}
    for f, (_, external, _) in GRAPH.items():
        if _layer(f) == "core":
            found |= {(f, name): "core runs without Blender" for name in external & NOT_IN_CORE}
    new = sorted(f"{f} imports {t}: {why}" for (f, t), why in found.items())
    assert not new, "imports upward across the layers:\n" + "\n".join(new)


def test_no_private_name_of_another_module():
    found = {(f, name) for f, (_, _, private) in GRAPH.items() for name in private}
    new = sorted(f"{f} reads {name}" for f, name in found)
    assert not new, "private names read from another module (make them public or keep them inside):\n" + "\n".join(new)


def _technique(path: str) -> str | None:
    """The technique folder ``path`` is in (core/techniques/<name>/...), or None."""
    parts = path.split("/")
    return parts[2] if len(parts) > 3 and parts[:2] == ["core", "techniques"] else None


def test_no_technique_imports_another():
    bad = []
    for f, (edges, _, _) in GRAPH.items():
        own = _technique(f)
        for target in edges:
            other = _technique(target)
            if own and other and other != own and other not in COMPOSES.get(own, ()):
                bad.append(f"{f} imports {target}")
            if not own and other and f.startswith("core/") and not f.startswith("core/techniques/registry"):
                if _dotted(f).startswith(CORE_LAYERS[:4]) or f in (
                    "core/techniques/spec.py",
                    "core/techniques/params.py",
                ):
                    bad.append(f"{f} imports the technique {target}")
    assert not bad, "technique folders stand side by side on core.optics:\n" + "\n".join(sorted(bad))
