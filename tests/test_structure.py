"""The shape of the code base: what the project holds itself to, checked on every run.

- no import cycle between kisscal's packages (imports inside functions count too);
- no module over 500 lines and no function with a body over 80 lines in ``kisscal/``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "kisscal"
MAX_MODULE_LINES = 500
MAX_FUNCTION_BODY_LINES = 80


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "data" not in p.relative_to(PACKAGE).parts)


def _unit(path: Path) -> str:
    """The package a module belongs to (``kisscal.detect``), or the module itself."""
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:2]) if len(parts) > 2 or path.name == "__init__.py" else ".".join(parts)


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
    return {".".join(n.split(".")[:2]) for n in names if n.startswith("kisscal.")}


def import_graph() -> dict[str, set[str]]:
    """Which kisscal package imports which (an edge a -> b: a imports b)."""
    graph: dict[str, set[str]] = {}
    for path in _modules():
        unit = _unit(path)
        graph.setdefault(unit, set()).update(i for i in _imports(path) if i != unit)
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


# The session runner may call into the report and the CLI into the session, never back.
# Two edges are conveniences that close a loop on purpose: the rig's loader calls the
# session runner (documented on Rig.load), and the generator of the shipped marker-set
# files (``python -m kisscal.markersets.derive``, a developer's tool) reads the KISS set
# off kisscal's synthetic walker.
ALLOWED = {("kisscal.rig", "kisscal.session"), ("kisscal.markersets", "kisscal.synth")}


def test_no_import_cycle_between_packages() -> None:
    graph = {a: {b for b in bs if (a, b) not in ALLOWED} for a, bs in import_graph().items()}
    assert _cycle(graph) is None, " -> ".join(_cycle(graph) or [])


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


STAGES = ("detect", "grid", "dlt", "bundle", "target", "recon", "tracking", "gait")
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
