"""The layers of core/ (design rules): no module may import qgis or PyQt (core/ runs without QGIS),
nor ``simulation/`` or ``ui/`` (they sit on top of it); its packages import only downwards
(foundation < model < formats < observations < adjust < products < measure), with no import
circle, no private name imported from another module and no import hidden in a function; no
module is longer than 500 lines."""
import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CORE = REPO / "core"
FORBIDDEN = ("qgis", "PyQt4", "PyQt5", "PyQt6", "sip")
ABOVE_CORE = ("simulation", "ui")
# Each package of core/ and its rank; modules directly in core/ are the foundation (rank 0).
LAYERS = ("model", "formats", "observations", "adjust", "products", "measure", "runs")
MAX_LINES = 500


def _imported_modules(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.append(node.module)
    return names


def _module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, root: Path, modules: set[str]) -> list[tuple[str, str | None, bool]]:
    """(imported module, imported name or None, inside a function) for every import of ``path``,
    relative ones resolved against the repository ``root``; ``from . import x`` of a submodule x
    names the submodule."""
    tree = ast.parse(path.read_text(), filename=str(path))
    name = _module_name(path, root)
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    in_function = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                   for n in ast.walk(f)}
    out = []
    for node in ast.walk(tree):
        nested = id(node) in in_function
        if isinstance(node, ast.Import):
            out += [(a.name, None, nested) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            target = ".".join(base + ([node.module] if node.module else []))
            for a in node.names:
                full = f"{target}.{a.name}"
                out.append((full, None, nested) if full in modules else (target, a.name, nested))
    return out


def _graph(root: Path, folders=("core",)) -> dict[str, list[tuple[str, str | None, bool]]]:
    files = {_module_name(p, root): p for folder in folders for p in sorted((root / folder).rglob("*.py"))}
    return {m: _imports(p, root, set(files)) for m, p in files.items()}


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, stack, on_stack, found, counter = {}, {}, [], set(), [], [0]
    for start in edges:
        if start in index:
            continue
        work = [(start, iter(edges.get(start, ())))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            v, children = work[-1]
            w = next(children, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(edges.get(w, ()))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                component = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    component.append(w)
                    if w == v:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def _rank(module: str) -> int:
    parts = module.split(".")
    return LAYERS.index(parts[1]) + 1 if len(parts) > 1 and parts[1] in LAYERS else 0


def _problems(root: Path) -> dict[str, list[str]]:
    graph = _graph(root)
    edges = {m: {t for t, _, _ in imports if t in graph and t != m} for m, imports in graph.items()}
    problems = {"qt": [], "above": [], "cycles": [" -> ".join(c) for c in _cycles(edges)], "upwards": [],
                "private": [], "in_function": [], "long": []}
    for m, imports in graph.items():
        for target, name, nested in imports:
            head = target.split(".")[0]
            if head in FORBIDDEN:
                problems["qt"].append(f"{m}: {target}")
            if head in ABOVE_CORE or target.startswith(tuple(f"pushbroom_adjust.{a}" for a in ABOVE_CORE)):
                problems["above"].append(f"{m}: {target}")
            if target not in graph or target == m:
                continue
            if _rank(target) > _rank(m):
                problems["upwards"].append(f"{m} -> {target}")
            if name and name.startswith("_") and not name.startswith("__"):
                problems["private"].append(f"{m}: {name} from {target}")
            if nested:
                problems["in_function"].append(f"{m} -> {target}")
    for p in (root / "core").rglob("*.py"):
        n = len(p.read_text().splitlines())
        if n > MAX_LINES:
            problems["long"].append(f"{p.relative_to(root)}: {n} lines")
    return problems


def test_core_does_not_import_qgis_or_qt():
    files = sorted(CORE.rglob("*.py"))
    assert len(files) >= 10  # the scan really sees the core
    offenders = [f"{f.relative_to(CORE.parent)}: import {m}" for f in files for m in _imported_modules(f)
                 if m.split(".")[0] in FORBIDDEN]
    assert not offenders, "core/ must not depend on QGIS/Qt:\n" + "\n".join(offenders)


def test_scanner_catches_both_import_forms(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import os\nfrom qgis.core import QgsPointXY\nif True:\n    import PyQt5.QtCore\n")
    assert [m for m in _imported_modules(bad) if m.split(".")[0] in FORBIDDEN] == ["qgis.core", "PyQt5.QtCore"]


def test_core_layers_are_clean():
    assert len(_graph(REPO)) >= 40  # the scan really sees the core's modules
    problems = _problems(REPO)
    assert problems == {k: [] for k in problems}, "\n".join(f"{k}: {v}" for k, v in problems.items() if v)


def test_layer_scanner_finds_each_kind_of_problem(tmp_path):
    """A small core/ with one problem of each kind: every one is named."""
    core = tmp_path / "core"
    for folder in ("model", "adjust"):
        (core / folder).mkdir(parents=True)
        (core / folder / "__init__.py").write_text("")
    (core / "__init__.py").write_text("")
    (core / "errors.py").write_text("from .model.camera import Camera\n")                      # runs back up
    (core / "geodesy.py").write_text("_hidden = 1\n")
    (core / "model" / "sensor.py").write_text("from ..geodesy import _hidden\nclass Scene: pass\n"
                                              "def f():\n    from .camera import Camera\n")
    (core / "model" / "camera.py").write_text("from .sensor import Scene\nfrom ...ui import dock\n"
                                              "import qgis.core\nclass Camera: pass\n")
    (core / "adjust" / "engine.py").write_text("from .. import errors\n" + "x = 1\n" * MAX_LINES)
    problems = _problems(tmp_path)
    assert problems["cycles"] == ["core.model.camera -> core.model.sensor"]
    assert problems["upwards"] == ["core.errors -> core.model.camera"]
    assert problems["private"] == ["core.model.sensor: _hidden from core.geodesy"]
    assert problems["in_function"] == ["core.model.sensor -> core.model.camera"]
    assert problems["above"] == ["core.model.camera: ui"] and problems["qt"] == ["core.model.camera: qgis.core"]
    assert problems["long"] == [f"core/adjust/engine.py: {MAX_LINES + 1} lines"]


def test_the_whole_plugin_has_no_circles_private_imports_or_hidden_imports():
    """simulation/ and ui/ too: no import circle, no private name imported from another module, no import
    of the plugin's own modules inside a function."""
    graph = _graph(REPO, ("core", "simulation", "ui"))
    assert any(m.startswith("simulation.") for m in graph) and any(m.startswith("ui.") for m in graph)
    edges = {m: {t for t, _, _ in imports if t in graph and t != m} for m, imports in graph.items()}
    private = [f"{m}: {n} from {t}" for m, imports in graph.items() for t, n, _ in imports
               if t in graph and t != m and n and n.startswith("_") and not n.startswith("__")]
    hidden = [f"{m} -> {t}" for m, imports in graph.items() for t, _, nested in imports if t in graph and nested]
    assert (_cycles(edges), private, hidden) == ([], [], [])
