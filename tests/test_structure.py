"""The shape of the code base: what the project holds itself to, checked on every run.

- no import cycle between kisscal's modules, nor between its packages (imports inside
  functions count too, and so do the names a package's ``_LAZY`` table imports on use);
- no upward import: a layer never imports one above it (:data:`LAYERS`);
- no import of another module's private name (``_x``);
- no module over 500 lines and no function with a body over 80 lines in ``kisscal/``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from functools import cache
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "kisscal"
MAX_MODULE_LINES = 500
MAX_FUNCTION_BODY_LINES = 80


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "data" not in p.relative_to(PACKAGE).parts)


def _name(path: Path) -> str:
    """The dotted name of a module (``kisscal.detect`` for its ``__init__.py``)."""
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if path.name == "__init__.py" else parts)


def _unit(module: str) -> str:
    """The package a module belongs to (``kisscal.detect``), or a top-level module itself."""
    return ".".join(module.split(".")[:2])


@cache
def _module_names() -> frozenset[str]:
    return frozenset(_name(p) for p in _modules())


def _target(module: str, name: str | None = None) -> str:
    """The kisscal module an import runs: ``from a.b import c`` runs ``a.b.c`` when that is
    a module, else ``a.b`` (or its nearest enclosing module)."""
    known = _module_names()
    if name is not None and f"{module}.{name}" in known:
        return f"{module}.{name}"
    while module not in known and "." in module:
        module = module.rsplit(".", 1)[0]
    return module


def _is_type_checking(node: ast.If) -> bool:
    return "TYPE_CHECKING" in ast.unparse(node.test)


def _import_nodes(tree: ast.AST) -> Iterator[ast.Import | ast.ImportFrom]:
    """Every import statement of a module, wherever it stands (in a function too), except
    under ``if TYPE_CHECKING:`` (never run)."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
        elif isinstance(node, ast.If) and _is_type_checking(node):
            yield from _import_nodes(ast.Module(body=node.orelse, type_ignores=[]))
        else:
            yield from _import_nodes(node)


def _lazy_table(tree: ast.Module) -> set[str]:
    """Modules a package imports on first use of a name, by its ``_LAZY`` table."""
    for node in tree.body:
        if (
            isinstance(node, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == "_LAZY" for t in node.targets)
            and isinstance(node.value, ast.Dict)
        ):
            return {v.value for v in node.value.values if isinstance(v, ast.Constant)}
    return set()


@cache
def _parsed(path: Path) -> ast.Module:
    return ast.parse(path.read_text())


def module_imports(path: Path) -> dict[str, list[str]]:
    """The kisscal modules a module imports, each with the names it takes from it."""
    found: dict[str, list[str]] = {}
    tree = _parsed(path)
    for node in _import_nodes(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("kisscal"):
                    found.setdefault(_target(alias.name), [])
        elif node.level == 0 and node.module and node.module.startswith("kisscal"):
            found.setdefault(_target(node.module), [])  # ``from a import b`` runs ``a`` first
            for alias in node.names:
                found.setdefault(_target(node.module, alias.name), []).append(alias.name)
        elif node.level:
            raise AssertionError(f"{path}: relative import; kisscal imports by full name")
    for lazy in _lazy_table(tree):
        found.setdefault(_target(lazy), [])
    found.pop(_name(path), None)
    return found


def module_graph() -> dict[str, set[str]]:
    """Which kisscal module imports which (an edge a -> b: a imports b)."""
    return {_name(p): set(module_imports(p)) for p in _modules()}


def import_graph() -> dict[str, set[str]]:
    """Which kisscal package imports which (an edge a -> b: a imports b)."""
    graph: dict[str, set[str]] = {}
    for module, imported in module_graph().items():
        unit = _unit(module)
        graph.setdefault(unit, set()).update(_unit(i) for i in imported if _unit(i) != unit)
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_no_import_cycle_between_packages() -> None:
    graph = import_graph()
    assert _cycle(graph) is None, " -> ".join(_cycle(graph) or [])


def test_no_import_cycle_between_modules() -> None:
    """A cycle hidden in a function (an import deferred to break it) counts as one."""
    graph = module_graph()
    assert _cycle(graph) is None, " -> ".join(_cycle(graph) or [])


def test_the_import_finder_sees_imports_in_functions_and_skips_type_checking() -> None:
    source = (
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from kisscal.c import y\nelse:\n    import kisscal.d\n"
        "def load():\n    if True:\n        from kisscal.b import x\n"
    )
    found = [
        n.module if isinstance(n, ast.ImportFrom) else n.names[0].name
        for n in _import_nodes(ast.parse(source))
    ]
    assert found == ["typing", "kisscal.d", "kisscal.b"]
    assert _cycle({"kisscal.a": {"kisscal.b"}, "kisscal.b": {"kisscal.a"}}) is not None
    assert _cycle({"kisscal.a": {"kisscal.b"}, "kisscal.b": set()}) is None


# Layers from the bottom: a module imports only its own layer and those below it.
# Stage packages work on arrays; io reads and writes files; synth makes labs with known
# truth for the session to write through io; the report reads out/; the session runs
# stages, writes through io and draws through the report; the CLI parses.
BASE = ("kisscal", "kisscal.errors", "kisscal.params", "kisscal._shared", "kisscal._text")
STAGES = ("detect", "grid", "dlt", "bundle", "target", "recon", "tracking", "gait")
ARRAYS = (*STAGES, "camera", "rig", "opencv", "markersets")
LAYERS = (
    BASE,
    tuple(f"kisscal.{p}" for p in ARRAYS),
    ("kisscal.io",),
    ("kisscal.synth",),
    ("kisscal.report",),
    ("kisscal.session",),
    ("kisscal.cli", "kisscal.__main__"),
)


def _layer(unit: str) -> int:
    return next(i for i, layer in enumerate(LAYERS) if unit in layer)


def test_every_package_has_a_layer() -> None:
    for unit in import_graph():
        assert any(unit in layer for layer in LAYERS), unit


@pytest.mark.parametrize(
    ("low", "high"),
    [
        ("rig", "session"),
        ("io", "synth"),
        ("markersets", "synth"),
        ("io", "report"),
        ("detect", "io"),
    ],
)
def test_the_layers_forbid_the_arrows_issue_24_names(low: str, high: str) -> None:
    assert _layer(f"kisscal.{low}") < _layer(f"kisscal.{high}")


def test_no_upward_import() -> None:
    """``rig`` never imports ``session``, ``io`` never ``synth`` (nor ``report`` ...)."""
    upward = [
        f"{module} -> {imported}"
        for module, targets in module_graph().items()
        for imported in sorted(targets)
        if _layer(_unit(imported)) > _layer(_unit(module))
    ]
    assert not upward, upward


def test_no_private_name_imported_from_another_module() -> None:
    """A name starting with ``_`` belongs to its module: share it by making it public."""
    private = [
        f"{_name(path)} imports {name} from {module}"
        for path in _modules()
        for module, names in module_imports(path).items()
        for name in names
        if name.startswith("_") and f"{module}.{name}" not in _module_names()
    ]
    assert not private, private


def _long_functions(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            body = node.body
            first = body[1] if isinstance(body[0], ast.Expr) and len(body) > 1 else body[0]
            length = node.end_lineno - first.lineno + 1
            if length > MAX_FUNCTION_BODY_LINES:
                found.append(
                    f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {node.name} {length}"
                )
    return found


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_modules_and_functions_fit_on_a_screen(path: Path) -> None:
    lines = len(path.read_text().splitlines())
    assert lines <= MAX_MODULE_LINES, f"{path.name}: {lines} lines"
    assert not _long_functions(path)


RUNNERS = ("io", "session", "report", "cli")


@pytest.mark.parametrize("stage", STAGES)
def test_stages_import_no_file_or_session_layer(stage: str) -> None:
    """A stage works on arrays: it never imports the layers that read files or run sessions."""
    imported = import_graph()[f"kisscal.{stage}"]
    assert not imported & {f"kisscal.{r}" for r in RUNNERS}, sorted(imported)


# The names of ``out/``'s folders and files (DESIGN.md): only kisscal.io.store joins them.
OUT_NAMES = {
    "out",
    "detection",
    "cache",
    "blobs",
    "linearisation",
    "dlt",
    "figures",
    "opencv",
    "pose2sim",
    "Calib_kisscal.toml",
    "summary.json",
    "report.html",
    "limits.json",
    "exports.json",
    "cameras.toml",
    "dltdv.csv",
    "wand.json",
    "check.json",
    "calibration.json",
    "target.json",
    "points3d.csv",
    "points2d.csv",
    "recon.json",
    "trajectories.csv",
    "trajectories.c3d",
    "trajectories.trc",
    "trajectories_cameras.csv",
    "tracking.json",
    "sweep.csv",
    "subject_template.json",
    "events.csv",
    "spatiotemporal.csv",
    "gait.json",
}
STORE = PACKAGE / "io" / "store.py"


def hand_built_out_paths(path: Path) -> list[int]:
    """Lines of ``path`` that join a path under ``out/`` by hand: a ``/`` chain naming a
    folder or file of the layout (or starting from an ``out_dir(...)`` call), or a
    ``.with_name(...)`` to one of its files."""
    tree = ast.parse(path.read_text())
    nested = {
        id(n.left) for n in ast.walk(tree) if isinstance(n, ast.BinOp) and isinstance(n.op, ast.Div)
    }
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div) and id(node) not in nested:
            parts, left = [], node
            while isinstance(left, ast.BinOp) and isinstance(left.op, ast.Div):
                parts.append(left.right)
                left = left.left
            names = {p.value for p in parts if isinstance(p, ast.Constant)}
            func = getattr(left, "func", None)
            by_out_dir = "out_dir" in (getattr(func, "id", None), getattr(func, "attr", None))
            if names & OUT_NAMES or by_out_dir:
                found.append(node.lineno)
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "with_name":
            arg = node.args[0] if node.args else None
            if isinstance(arg, ast.Constant) and arg.value in OUT_NAMES:
                found.append(node.lineno)
    return sorted(found)


def test_hand_built_out_paths_are_found(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text(
        "from pathlib import Path\n"
        "a = Path('s') / 'out' / 'x'\n"
        "b = Path('s') / 'trials' / 'walk'\n"  # an input folder, not out/
        "c = a.with_name('recon.json')\n"
        "d = out_dir(root) / 'trials'\n"
        "e = tdir / f'{cam}.json' / 'dlt'\n"
    )
    assert hand_built_out_paths(module) == [2, 4, 5, 6]


def test_only_the_store_builds_out_paths() -> None:
    """Every path under ``out/`` comes from :class:`kisscal.io.store.SessionStore`."""
    found = [
        f"{path.relative_to(PACKAGE.parent)}:{line}"
        for path in _modules()
        if path != STORE
        for line in hand_built_out_paths(path)
    ]
    assert not found, found


def test_only_the_store_computes_cache_keys() -> None:
    """One function keys a stage's inputs (``SessionStore.key``): nothing else hashes."""
    hashing = [p.name for p in _modules() if p != STORE and "hashlib" in _all_imports(p)]
    assert not hashing, hashing


def _all_imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    return names | {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
