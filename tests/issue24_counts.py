"""Measure the counts of issue 24's "done when" and print them as a table.

Run from the repository root (``--trace`` also traces ``[detection] threshold`` through a
small image session, a few seconds)::

    PYTHONPATH=$PWD python tests/issue24_counts.py --trace

What each row counts, and how:

- hand-built ``out/`` paths outside the store: lines that join a path of the layout by
  hand (:func:`test_structure.hand_built_out_paths`, the check the structure test runs);
- cache-key sites: modules whose functions hash a stage's inputs (a ``hashlib`` call; the
  functions are listed), and, beside them, the calls of the one key function
  ``store.key(...)`` (uses, not key computations);
- hops of ``[detection] threshold``: with ``--trace``, a session's ``session.toml`` sets
  a threshold no survey would derive and the runner runs a trial stage on it
  (:func:`kisscal.session.runner.run_trial`: load, resolve, derive the cameras'
  settings, key, detect the trial, hand the stage its blobs) under a profiler;
  every kisscal function of another module that receives the value in an argument (a
  table, a ``DetectionParams``, the ``StageParams``, a detection or survey job, a
  recorded setting, ``*args`` included) is a hand-over: a hop when it passes the value
  on (returns it, hands it to another module, or is the detector's pool), an end when
  the value stops there (a cache key, a log line, a record written); the detection
  record read back after it was written in the same run would be a disk round trip;
- camera classes: classes named ``*Camera``, and whether they project; Brown
  implementations: functions whose code (docstrings aside) names ``k1`` and ``r2`` on one
  line, listed for a reader to tell a lens model from code that only draws coefficients;
- cycles and upward arrows: the structure test's own graph (imports inside functions
  included, so a lazy import cannot hide a cycle); lazy imports are counted beside;
- lines: every ``.py`` line under ``kisscal/``, per package;
- architecture page: packages of ``kisscal/`` without a ``**`name`**`` paragraph.
"""

from __future__ import annotations

import ast
import inspect
import re
import sys
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE / "session")]

import test_structure as ts  # noqa: E402

ROOT = HERE.parent
PACKAGE = ROOT / "kisscal"


def out_paths() -> list[str]:
    return [
        f"{p.relative_to(ROOT)}:{line}"
        for p in ts._modules()
        if p != ts.STORE
        for line in ts.hand_built_out_paths(p)
    ]


def _functions(tree: ast.AST) -> list[ast.FunctionDef | ast.AsyncFunctionDef]:
    return [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)]


def key_sites() -> tuple[list[str], int]:
    """Functions calling ``hashlib`` anywhere in kisscal, and calls of ``.key(``."""
    hashing, uses = [], 0
    for path in ts._modules():
        tree = ts._parsed(path)
        for f in _functions(tree):
            if any(
                isinstance(n, ast.Attribute) and getattr(n.value, "id", "") == "hashlib"
                for n in ast.walk(f)
            ):
                hashing.append(f"{path.relative_to(ROOT)}:{f.name}")
        uses += sum(
            1
            for n in ast.walk(tree)
            if isinstance(n, ast.Call) and getattr(n.func, "attr", None) == "key"
        )
    return hashing, uses


def camera_classes() -> list[str]:
    found = []
    for path in ts._modules():
        for node in ast.walk(ts._parsed(path)):
            if isinstance(node, ast.ClassDef) and node.name.endswith("Camera"):
                projects = any(
                    isinstance(f, ast.FunctionDef) and f.name.startswith("project")
                    for f in node.body
                )
                found.append(
                    f"{path.relative_to(ROOT)}:{node.name}"
                    + (" (projects)" if projects else " (no projection)")
                )
    return found


def brown() -> list[str]:
    """Functions whose source multiplies k1 and r2 (the radial polynomial of a lens)."""
    pattern = re.compile(r"\bk1\b[^\n]*\br2\b|\br2\b[^\n]*\bk1\b")
    found = []
    for path in ts._modules():
        text = path.read_text()
        for f in _functions(ts._parsed(path)):
            body = "\n".join(text.splitlines()[f.lineno - 1 : f.end_lineno])
            code = re.sub(r'""".*?"""', "", body, flags=re.S)  # docstrings state formulas
            if pattern.search(code) and not any(
                g is not f and g.lineno > f.lineno and g.end_lineno <= f.end_lineno
                for g in _functions(ts._parsed(path))
            ):
                found.append(f"{path.relative_to(ROOT)}:{f.name}")
    return found


def lazy_imports() -> int:
    """kisscal imports inside functions (each would count in a cycle: the graph has them)."""
    n = 0
    for path in ts._modules():
        for f in _functions(ts._parsed(path)):
            n += sum(
                1
                for s in ast.walk(f)
                if isinstance(s, ast.ImportFrom) and (s.module or "").startswith("kisscal")
            )
    return n


def upward() -> list[str]:
    return [
        f"{m} -> {i}"
        for m, targets in ts.module_graph().items()
        for i in sorted(targets)
        if ts._layer(ts._unit(i)) > ts._layer(ts._unit(m))
    ]


def lines() -> Counter:
    per: Counter = Counter()
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE).parts
        per[parts[0] if len(parts) > 1 else "(top-level modules)"] += len(
            path.read_text().splitlines()
        )
    return per


def undocumented() -> list[str]:
    page = (ROOT / "docs" / "architecture.md").read_text()
    names = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").is_file()}
    names |= {p.name for p in PACKAGE.glob("*.py") if not p.name.startswith("_")}
    names -= {"data", "errors.py", "params.py"}  # data files; the bottom layer's own section
    return sorted(n for n in names if f"**`{n}`**" not in page)


# ------------------------------------------------------------------ the threshold traced

SENTINEL = 137.25  # a threshold no survey derives


def _carries(obj: object, depth: int = 0) -> bool:
    """Whether ``obj`` holds the sentinel threshold (in a table, a dataclass, a job, a
    recorded setting ``{"threshold": Setting(value, ...)}``); the whole ``SessionConfig``
    is not counted (it goes everywhere): its two hand-overs of the table, parsing and
    resolving, are counted by name in :func:`trace_threshold`."""
    if depth > 4 or obj is None or isinstance(obj, str | bytes | int | float | Path):
        return False
    if type(obj).__name__ == "SessionConfig":
        return False
    if getattr(obj, "threshold", None) == SENTINEL and not isinstance(obj, type):
        return True
    if isinstance(obj, dict):
        given = obj.get("threshold")
        if given == SENTINEL or getattr(given, "value", None) == SENTINEL:
            return True
        return any(_carries(v, depth + 1) for v in list(obj.values())[:16])
    if isinstance(obj, list | tuple):
        return any(_carries(v, depth + 1) for v in obj[:16])
    if type(obj).__name__ == "partial":
        return _carries([*obj.args, *obj.keywords.values()], depth + 1)
    fields = getattr(obj, "__dataclass_fields__", None) or getattr(obj, "_fields", None)
    if fields:
        return any(_carries(getattr(obj, name, None), depth + 1) for name in fields)
    return False


def _arguments(frame) -> list[object]:
    """The values a call received: named, keyword-only, ``*args`` and ``**kwargs``."""
    code = frame.f_code
    n = code.co_argcount + code.co_kwonlyargcount
    n += bool(code.co_flags & inspect.CO_VARARGS) + bool(code.co_flags & inspect.CO_VARKEYWORDS)
    return [frame.f_locals.get(v) for v in code.co_varnames[:n]]


class _Tracer:
    """A profiler that records the hand-overs of the sentinel (see :func:`trace_threshold`)."""

    def __init__(self) -> None:
        self.order: list[str] = []
        self.passes: set[str] = set()
        self.open_calls: dict[int, str] = {}  # frames of hand-overs still running -> hop
        self.written: set[str] = set()
        self.round_trips: list[str] = []

    @staticmethod
    def module(frame) -> str:
        path = frame.f_code.co_filename
        if path == __file__:
            return "session/reconstruct"  # this script's stage stands for the command's
        if not path.startswith(str(PACKAGE)):
            return "?"  # generated code (a dataclass's __init__): not a hand-over
        name = str(Path(path).relative_to(PACKAGE).with_suffix(""))
        if name == "session/progress" and frame.f_back is not None:
            return _Tracer.module(frame.f_back)  # counts the items of a generator it iterates
        # one parse of the table (its reader), one resolution (the Params validator)
        return {"io/toml_table": "io/config", "params": "session/params"}.get(name, name)

    def handed_on(self, frame) -> None:
        """A hand-over below ``frame``: each hand-over still running above passed it on."""
        outer = frame.f_back
        while outer is not None:
            if id(outer) in self.open_calls:
                self.passes.add(self.open_calls[id(outer)])
            outer = outer.f_back

    def records(self, frame) -> None:
        """Note the detection records written, and those read back after (round trips)."""
        name, local = frame.f_code.co_name, frame.f_locals
        if name == "write_detection_record":
            self.written.add(Path(local["path"]).stem)
        if name == "detection_record" and local.get("camera") in self.written:
            self.round_trips.append(f"out/detection/{local['camera']}.json")

    def __call__(self, frame, event, arg):
        if not frame.f_code.co_filename.startswith(str(PACKAGE)):
            return
        if event == "return":
            hop = self.open_calls.pop(id(frame), None)
            if hop is not None and _carries(arg):
                self.passes.add(hop)
            return
        if event != "call":
            return
        self.records(frame)
        code, callee, caller = frame.f_code, self.module(frame), self.module(frame.f_back)
        if callee == caller or caller == "?" or caller.startswith("detect/"):
            return
        table = code.co_name in ("load_session", "stage_params")  # the table, parsed, resolved
        if table or any(_carries(a) for a in _arguments(frame)):
            hop = f"{caller} -> {callee}.{code.co_name}"
            if hop not in self.order:
                self.order.append(hop)
            if table or code.co_name == "detect_jobs":  # the detector's pool: the use
                self.passes.add(hop)
            self.handed_on(frame)
            self.open_calls[id(frame)] = hop


def trace_threshold(tmp: Path) -> tuple[list[str], list[str], list[str]]:
    """The hand-overs of ``[detection] threshold`` from ``session.toml`` to the detection
    of a trial: each call from one module into another whose arguments carry the value
    (calls within a module, and inside the detect package, are not hand-overs), with
    the stage's own functions (defined here, handed the blobs) standing for
    ``session/reconstruct``'s.

    Returns the hops (hand-overs that pass the value on: the callee returns it, or hands
    it on to another module before it returns, or is the detector's pool), the ends
    (hand-overs where the value stops: a cache key, a log line, a record written), and
    the detection records read back after being written in the same run (disk round
    trips)."""
    from test_every_parameter import _marker_session

    from kisscal.session.inputs import load_config
    from kisscal.session.runner import TrialStage, run_trial

    root = _marker_session(tmp, {"threshold": SENTINEL})
    handed: list[object] = []  # what the stage was handed (its blobs must be detected)
    stage = TrialStage(
        "reconstruct",
        inputs=lambda run: (),
        output=lambda files: (files.points3d, False),
        cached=lambda run: None,
        compute=lambda run, inputs, blobs: handed.append(blobs),
        without_blobs=lambda run: None,
    )
    tracer = _Tracer()
    sys.setprofile(tracer)
    try:
        run_trial(stage, load_config(root), "walk", workers=1)
    finally:
        sys.setprofile(None)
    assert handed and any(len(f) for b in handed for f in b.values()), "no blobs handed on"
    hops = [h for h in tracer.order if h in tracer.passes]
    ends = [h for h in tracer.order if h not in tracer.passes]
    return hops, ends, tracer.round_trips


def main() -> None:
    rows = []
    paths = out_paths()
    rows.append(("hand-built out/ paths outside the store", "38", len(paths), paths))
    hashing, uses = key_sites()
    modules = {h.split(":")[0] for h in hashing}
    rows.append(("cache-key sites (modules hashing)", "10", len(modules), hashing))
    rows.append(("  calls of store.key(...) (uses of the one key)", "", uses, []))
    cams = camera_classes()
    rows.append(("classes named *Camera", "4", len(cams), cams))
    b = brown()
    rows.append(("functions computing k1 * r2 (radial lens terms)", "3", len(b), b))
    module_cycle = ts._cycle(ts.module_graph())
    package_cycle = ts._cycle(ts.import_graph())
    rows.append(("module import cycles (lazy included)", "", int(bool(module_cycle)), []))
    rows.append(("package import cycles", "", int(bool(package_cycle)), []))
    up = upward()
    rows.append(("upward imports", "", len(up), up))
    rows.append(("kisscal imports inside functions", "", lazy_imports(), []))
    gets = sum(p.read_text().count(".get(") for p in (PACKAGE / "report").glob("*.py"))
    rows.append(("  .get( calls in report/ (untyped reads)", "62", gets, []))
    loads = sum(
        1
        for p in ts._modules()
        for n in ast.walk(ts._parsed(p))
        if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "load_config"
    )
    rows.append(("  load_config calls", "12", loads, []))
    docs = undocumented()
    rows.append(("packages without a paragraph in architecture.md", "", len(docs), docs))
    per = lines()
    rows.append(("lines of kisscal/ (.py)", "35.5k", sum(per.values()), []))
    if "--trace" in sys.argv:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            hops, ends, round_trips = trace_threshold(Path(tmp))
        rows.append(("hops of [detection] threshold (module to module)", "12", len(hops), hops))
        rows.append(("  hand-overs where it ends (key, log, record)", "", len(ends), ends))
        rows.append(("  disk round trips on the way", "1", len(round_trips), round_trips))
    width = max(len(r[0]) for r in rows)
    print(f"{'count':<{width}}  {'issue':>6}  {'now':>6}")
    for name, issue, now, detail in rows:
        print(f"{name:<{width}}  {issue:>6}  {now:>6}")
        for d in detail:
            print(f"{'':<{width}}    {d}")
    print("\nlines per package:")
    for name, n in sorted(per.items()):
        print(f"  {name:<22} {n:>6}")


if __name__ == "__main__":
    main()
