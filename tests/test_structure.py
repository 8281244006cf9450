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
