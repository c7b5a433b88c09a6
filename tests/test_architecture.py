"""The layers of ``docs/architecture.md``: imports go down, never up, and no circle crosses folders.

Every ``import`` of ``mslab/`` is read with ``ast`` (top-level, inside functions and under
``TYPE_CHECKING`` alike: each is a dependency) and resolved to the file it loads. Two rules:

1. an import goes down the list of layers (:data:`LAYERS`, as in ``docs/architecture.md``
   and the design's "Layers"), or stays in its layer; ``grading/`` stands apart: only
   ``commands/`` imports it, and of grading only ``problems.py`` and ``checks.py`` import
   the library (beyond the leaves);
2. no import circle joins files of different folders.

No exceptions: a lower layer that needs something from above gets it handed down (the
order check of the registry, the predicted stable dt of the run's pre-check: both installed
by ``mslab/__init__.py``). Also checked: builder methods are visible to tools (attributes
of ``SceneBuilder`` listed in its class body), the integrator discovery's exclusion list is
right, and effects are picked by capability, never by name or class, outside ``effects/``.
"""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "mslab"

#: the layers, top (imports everything below) to bottom (imports nothing of mslab): each a
#: list of path patterns relative to mslab/ (``fnmatch`` style; a folder ``x/`` means every file in it)
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("commands/, cli, demo, lesson_mistakes, claims_order",
     ("__init__.py", "__main__.py", "cli.py", "demo.py", "lesson_mistakes.py", "claims_order.py",
      "commands/")),
    ("plots/", ("plots/",)),
    ("stability/, derive/, precision/, budget", ("stability/", "derive/", "precision/", "budget.py")),
    ("scenes/ (builder, loader, generators)", ("scenes/",)),
    ("simulate (Simulation, simulate, ledger, stopping)",
     ("simulate.py", "simulation.py", "stepping.py", "steps.py", "stopping.py", "ledger.py",
      "trajectory.py", "initial.py", "owned.py")),
    ("fast/", ("fast/",)),
    ("integrators/ (families, catalogue, newton)", ("integrators/",)),
    ("Scene, Settings, schema", ("scene.py",)),
    ("system", ("system.py",)),
    ("effects/", ("effects/",)),
    ("errors, state, files, progress, threads, one jit helper",
     ("errors.py", "state.py", "files.py", "progress.py", "threads.py", "claims.py", "interrupts.py",
      "jit.py", "compiled_sources.py", "lanes.py", "kicks.py", "checks.py", "exercise_cells.py")),
]
GRADING = "grading/"
#: files of grading/ that talk to the library (the problems and their checks)
GRADING_LIBRARY_FILES = ("grading/problems.py", "grading/checks.py")

def _layer_of(rel: str) -> int | None:
    """Index in LAYERS of the file ``rel`` (most specific pattern wins); None for grading/."""
    if rel.startswith(GRADING):
        return None
    best, length = None, -1
    for index, (_, patterns) in enumerate(LAYERS):
        for p in patterns:
            hit = rel.startswith(p) if p.endswith("/") else rel == p
            if hit and len(p) > length:
                best, length = index, len(p)
    assert best is not None, f"mslab/{rel} belongs to no layer: add it to LAYERS and docs/architecture.md"
    return best


def _module_file(module: str) -> str | None:
    """File (relative to mslab/) that ``import module`` loads, or None when it is not mslab's."""
    if module != "mslab" and not module.startswith("mslab."):
        return None
    parts = module.split(".")[1:]
    base = PACKAGE.joinpath(*parts)
    if base.with_suffix(".py").is_file():
        return str(base.with_suffix(".py").relative_to(PACKAGE))
    if (base / "__init__.py").is_file():
        return str((base / "__init__.py").relative_to(PACKAGE))
    return None


def _imports(path: Path) -> set[str]:
    """Files (relative to mslab/) that the file at ``path`` imports, by any import statement.

    With the ``__init__.py`` of every package on the way: ``import mslab.fast.jit`` runs
    ``mslab/fast/__init__.py`` first — except the packages that hold ``path`` itself, which
    ran before this file could (``integrators/families/x.py`` importing ``mslab.integrators.base``
    adds no dependency on ``integrators/__init__.py``; ``from mslab.integrators import y`` does).
    """
    rel_dir = path.parent.relative_to(ROOT).parts
    own = {"/".join(rel_dir[1:k]) + "/__init__.py" for k in range(2, len(rel_dir) + 1)}
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:
                package = list(rel_dir[: len(rel_dir) - node.level + 1])
                module = ".".join(package + ([module] if module else []))
            names = []
            for alias in node.names:  # ``from mslab.x import y``: y may be a module itself
                sub = _module_file(f"{module}.{alias.name}")
                names.append(f"{module}.{alias.name}" if sub else module)
        else:
            continue
        for f in filter(None, map(_module_file, names)):
            out.add(f)
            parts = f.split("/")[:-1]  # importing a.b.c runs a/__init__ and a/b/__init__ first
            out.update({"/".join(parts[:k]) + "/__init__.py" for k in range(1, len(parts) + 1)} - own)
    out.discard(str(path.relative_to(PACKAGE)))
    return out


def _graph() -> dict[str, set[str]]:
    files = sorted(PACKAGE.rglob("*.py"))
    return {str(p.relative_to(PACKAGE)): _imports(p) for p in files}


GRAPH = _graph()


def _folder(rel: str) -> str:
    return str(Path(rel).parent)


def test_every_file_has_a_layer():
    for rel in GRAPH:
        _layer_of(rel)


def _upward_imports() -> dict[tuple[str, str], str]:
    bad = {}
    for src, targets in GRAPH.items():
        for dst in targets:
            if src == dst:
                continue
            ls, ld = _layer_of(src), _layer_of(dst)
            if ls is None:  # grading: the library only through problems and checks (and the leaves)
                if ld is not None and ld < len(LAYERS) - 1 and src not in GRADING_LIBRARY_FILES:
                    bad[src, dst] = f"grading/ file imports the library layer '{LAYERS[ld][0]}'"
                continue
            if ld is None:
                if not src.startswith("commands/"):
                    bad[src, dst] = "only commands/ imports grading/"
                continue
            if ld < ls:
                bad[src, dst] = f"layer '{LAYERS[ls][0]}' imports the higher layer '{LAYERS[ld][0]}'"
    return bad


def test_imports_go_down_the_layers():
    bad = _upward_imports()
    assert not bad, "\n".join(f"mslab/{s} -> mslab/{d}: {why}" for (s, d), why in sorted(bad.items()))


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one file (Tarjan, iterative)."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in graph:
                    continue
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        out.append(sorted(component))
    return out


def test_no_import_circle_across_folders():
    crossing = [c for c in _cycles(GRAPH) if len({_folder(f) for f in c}) > 1]
    assert not crossing, "import circles across folders:\n" + "\n".join(", ".join(c) for c in crossing)


def test_the_checker_sees_an_upward_import_and_a_circle():
    """The two rules on a made-up graph: they can fail."""
    assert _cycles({"a/x.py": {"b/y.py"}, "b/y.py": {"a/x.py"}}) == [["a/x.py", "b/y.py"]]
    assert _cycles({"a/x.py": {"b/y.py"}, "b/y.py": set()}) == []
    assert _layer_of("effects/springs.py") > _layer_of("scenes/builder.py")
    assert _layer_of("jit.py") == len(LAYERS) - 1 and _layer_of("fast/loops.py") == 5
    assert _imports(PACKAGE / "scenes" / "builder.py") >= {"scene.py", "effects/__init__.py", "errors.py"}
    families = _imports(PACKAGE / "integrators" / "families" / "runge_kutta.py")
    assert "integrators/base.py" in families and "integrators/__init__.py" not in families


# -- builder methods visible to tools ------------------------------------------------------------
def test_builder_methods_are_listed_in_the_class_body():
    """Every built-in effect's builder method is an attribute assigned in ``SceneBuilder``'s body."""
    from mslab.effects import registry
    from mslab.scenes.builder import SceneBuilder

    tree = ast.parse((PACKAGE / "scenes" / "builder.py").read_text())
    body = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "SceneBuilder").body
    listed = {t.id for n in body if isinstance(n, ast.Assign) for t in n.targets if isinstance(t, ast.Name)}
    builtin = [cls for cls in registry.effect_classes() if cls.__module__.startswith("mslab.effects.")]
    for cls in builtin:
        for name in cls.builder_methods:
            assert name in listed, f"{cls.__name__}.{name} not listed in SceneBuilder's class body"
            assert SceneBuilder.__dict__[name] is getattr(cls, name)  # one definition: the effect's
    assert "__getattr__" not in SceneBuilder.__dict__


# -- integrator discovery ----------------------------------------------------------------------
def test_integrator_discovery_skips_exactly_the_framework_modules():
    """catalogue/ and user files next to the package register methods; families/ and newton/ do not."""
    import mslab.integrators as package

    folder = PACKAGE / "integrators"
    top = {p.stem for p in folder.glob("*.py") if p.stem != "__init__"}
    assert package._FRAMEWORK <= top, f"no such modules: {package._FRAMEWORK - top}"
    for path in sorted(folder.rglob("*.py")):
        if path.stem == "__init__":
            continue
        text = path.read_text()
        calls, defines = re.search(r"\bregister\(", text), "def register(" in text
        where = str(path.relative_to(folder))
        if path.parent.name == "catalogue" or (path.parent == folder and path.stem not in package._FRAMEWORK):
            assert calls, f"integrators/{where} registers no method: move it out of catalogue/"
        else:
            assert not calls or defines, f"integrators/{where} registers methods but is not discovered"
    assert set(package._FOLDER_OF) == {p.stem for p in folder.glob("[fn]*/*.py") if p.stem != "__init__"}


# -- capabilities, not names or classes --------------------------------------------------------
EFFECT_CLASSES = ("Springs", "Gravity", "Damping", "Anchors", "Wind", "Plane", "Sphere", "PenaltyCollider")
EFFECT_NAMES = ("springs", "gravity", "damping", "anchors", "wind", "plane", "sphere")

def _picks(rel: str) -> list[str]:
    """``isinstance(..., EffectClass)`` calls and comparisons of ``.name`` with an effect's name."""
    return _picks_in(PACKAGE / rel)


def _picks_in(path: Path) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        call = isinstance(node, ast.Call) and getattr(node.func, "id", None) == "isinstance"
        if call and len(node.args) == 2:
            names = {n.id for n in ast.walk(node.args[1]) if isinstance(n, ast.Name)}
            out += [f"isinstance(..., {c})" for c in names & set(EFFECT_CLASSES)]
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            attrs = any(isinstance(s, ast.Attribute) and s.attr == "name" for s in sides)
            consts = {c.value for s in sides for c in ast.walk(s) if isinstance(c, ast.Constant)}
            if attrs and consts & set(EFFECT_NAMES):
                out.append(f".name compared with {sorted(consts & set(EFFECT_NAMES))}")
    return out


def test_effects_are_picked_by_capability_outside_effects():
    found = {rel: p for rel in GRAPH if not rel.startswith(("effects/", GRADING)) and (p := _picks(rel))}
    assert not found, found


def test_the_pick_finder_sees_a_name_and_a_class(tmp_path):
    """The capability rule on made-up code: it can fail."""
    (tmp_path / "x.py").write_text("a = [e for e in s if e.name in ('plane', 'sphere')]\n"
                                   "b = isinstance(e, Sphere)\n")
    assert sorted(_picks_in(tmp_path / "x.py")) == [".name compared with ['plane', 'sphere']",
                                                   "isinstance(..., Sphere)"]


@pytest.mark.parametrize("dim", [2, 3])
def test_capabilities_declared_by_the_effects(dim):
    """The capabilities say what the forces are: checked against the forces themselves."""
    import numpy as np

    import mslab

    b = mslab.SceneBuilder(dim=dim)
    rng = np.random.default_rng(1)
    b.add_particles(rng.normal(size=(5, dim)), mass=[1.0, 2.0, 1.5, 0.5, 1.0])
    b.add_springs([[0, 1], [1, 2], [2, 3], [3, 4]], stiffness=30.0, damping=0.4, rest_length=0.8)
    b.add_gravity(9.81)
    b.add_damping(gamma=0.3)
    b.add_plane([0.0] * (dim - 1) + [1.0], offset=0.0, stiffness=1e3)
    scene = b.build()
    x = rng.normal(size=(5, dim))
    v = rng.normal(size=(5, dim))
    zero = np.zeros_like(v)
    for e in scene.system.effects:
        springs, gamma, f0 = e.hooke_springs(), e.linear_drag(), e.constant_force()
        if springs is not None:  # Hooke's law from (i, j, k, L), independently of the effect's code
            d = x[springs.i] - x[springs.j]
            length = np.linalg.norm(d, axis=1)
            pair = (springs.stiffness * (springs.rest_length - length) / length)[:, None] * d
            expected = np.zeros_like(x)
            np.add.at(expected, springs.i, pair)
            np.add.at(expected, springs.j, -pair)
            np.testing.assert_allclose(e.force(x, zero), expected, rtol=1e-12, atol=1e-12)
        if gamma is not None:
            np.testing.assert_allclose(e.force(x, v), -gamma * v, rtol=1e-14)
        if f0 is not None:
            np.testing.assert_array_equal(e.force(x, v), f0)
            np.testing.assert_array_equal(e.force(2 * x, 3 * v), f0)
        if e.may_touch:  # every particle touching: the penalty's -k n n^T on each
            K = e.contact_jacobian(x).toarray()
            assert K.shape == (5 * dim, 5 * dim)
            np.testing.assert_allclose(np.diag(K)[dim - 1::dim], -1e3)
        shape = e.outline()
        if shape is not None:  # the plane's outline: no force on its surface, a penalty 0.01 below it
            assert type(shape).__name__ == "Halfspace" and e.may_touch
            p0 = (shape.offset * shape.normal)[None]
            np.testing.assert_allclose(e.force(p0, zero[:1]), 0.0, atol=1e-12)
            np.testing.assert_allclose(e.energy(p0 - 0.01 * shape.normal), 0.5e3 * 0.01**2, rtol=1e-9)
    kinds = {type(e).__name__: (e.hooke_springs() is not None, e.linear_drag() is not None,
                                e.constant_force() is not None, e.may_touch) for e in scene.system.effects}
    assert kinds == {"Springs": (True, False, False, False), "Gravity": (False, False, True, False),
                     "Damping": (False, True, False, False), "Plane": (False, False, False, True)}
    assert scene.springs() is scene.system.effects[0]
    importlib.import_module("mslab.scene")


# -- mslab bench from an installed package ---------------------------------------------------
def test_bench_from_an_installed_package_says_it_needs_a_checkout(tmp_path):
    """A copy of the package without the repository around it (as from a wheel): one line, exit 2."""
    import os
    import shutil
    import subprocess
    import sys

    shutil.copytree(PACKAGE, tmp_path / "site" / "mslab", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "site")}
    out = subprocess.run([sys.executable, "-m", "mslab", "bench", "--quick"], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.count("\n") == 1 and out.stderr.startswith("mslab: error: bench: needs a checkout")
    assert str(tmp_path / "site" / "mslab") in out.stderr


# -- sizes: modules under 400 lines, functions at most 80 --------------------------------------

def test_modules_and_functions_stay_small():
    long_modules, long_functions = [], []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel, text = str(path.relative_to(PACKAGE)), path.read_text()
        if text.count("\n") >= 400:
            long_modules.append(f"mslab/{rel}: {text.count(chr(10))} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = node.end_lineno - node.lineno + 1
                if length > 80:
                    long_functions.append(f"mslab/{rel}: {node.name}, {length} lines")
    assert not long_modules and not long_functions, long_modules + long_functions
