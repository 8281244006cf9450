"""Trace ``[detection] threshold`` from ``session.toml`` to blob detection, one camera.

Usage: ``python -m benchmarks.param_hops SESSION [CAMERA]`` on a copy of a session with a
grid and a trial of images (``kisscal synth`` makes one). The script sets ``[detection]
threshold`` in the copy's ``session.toml``, deletes ``out/detection`` and the blob cache,
then resolves the parameters, surveys the camera and detects its first trial, all in this
process (``workers=1``), and prints:

- every function of the session layer (and the stage entry points) that received the
  value (a ``DetectionParams``, the session's parameters, a mapping holding ``threshold``
  or one of ``DetectionParams`` per camera), in the order first called;
- where it changed form: each time parameters were built from a raw mapping
  (``Params.from_layers``) and each read of ``out/detection/<camera>.json``.

It works with the code of any branch (the signature of ``markers_detection`` changed).
"""

from __future__ import annotations

import dataclasses
import shutil
import sys
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import tomli_w

from kisscal.detect import DetectionParams
from kisscal.io.config import load_session, load_toml
from kisscal.params import Params
from kisscal.session import configure
from kisscal.session.params import stage_params
from kisscal.session.reconstruct import trial_blobs

THRESHOLD = 60.0


#: Stage functions the value enters by (their insides are not listed).
ENTRIES = ("configure_detection", "detect_jobs", "detect_sequence", "detect_blobs")


def _carries(value: Any) -> bool:
    if isinstance(value, DetectionParams) or type(value).__name__ == "StageParams":
        return True
    if isinstance(value, Mapping):
        return "threshold" in value or any(isinstance(v, DetectionParams) for v in value.values())
    return isinstance(value, list | tuple) and any(_carries(v) for v in value[:3])


def _tracer(path: list[str]) -> Any:
    def trace(frame: Any, event: str, _arg: Any) -> None:
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        code = frame.f_code
        layer = module.startswith(("kisscal.session", "kisscal.io", "kisscal._shared"))
        if not (layer or code.co_name in ENTRIES) or code.co_name.startswith("__"):
            return
        names = code.co_varnames[: code.co_argcount + code.co_kwonlyargcount]
        if any(_carries(frame.f_locals.get(n)) for n in names):
            where = f"{module}.{code.co_name}"
            if where not in path:
                path.append(where)

    return trace


def main(source: Path, camera: str = "cam1") -> None:
    root = Path(tempfile.mkdtemp()) / "s"
    shutil.copytree(source, root, ignore=shutil.ignore_patterns("out"))
    data = load_toml(root / "session.toml")
    data.setdefault("detection", {})["threshold"] = THRESHOLD
    (root / "session.toml").write_text(tomli_w.dumps(data))
    events: list[str] = []
    built = Params.__dict__["from_layers"].__func__
    read_text = Path.read_text

    def from_layers(cls: type, *layers: Any, **kw: Any) -> Any:
        if cls is DetectionParams and any("threshold" in layer for layer in layers):
            caller = sys._getframe(1)
            where = f"{caller.f_globals['__name__']}.{caller.f_code.co_name}"
            events.append(f"DetectionParams built from a mapping holding threshold in {where}")
        return built(cls, *layers, **kw)

    def read(self: Path, *a: Any, **k: Any) -> str:
        if self.parent.name == "detection" and self.suffix == ".json":
            events.append(f"read back {self.parent.name}/{self.name}")
        return read_text(self, *a, **k)

    Params.from_layers = classmethod(from_layers)  # type: ignore[method-assign]
    Path.read_text = read  # type: ignore[method-assign]
    path: list[str] = []
    sys.setprofile(_tracer(path))
    try:
        config = load_session(root)
        params = stage_params(config)
        cam = [c for c in config.cameras if c.id == camera]
        try:
            detection = configure.markers_detection(root, config, params, cameras=cam, workers=1)
        except (AttributeError, TypeError):  # before: the raw mapping was passed
            given = params.detection_given
            detection = configure.markers_detection(root, config, given, cameras=cam, workers=1)
        trial = next(t for t in config.trials if t.source in ("images", "video"))
        config = dataclasses.replace(config, cameras=tuple(cam))
        trial_blobs(root, config, trial, detection, lambda _s: None, workers=1)
    finally:
        sys.setprofile(None)
        Params.from_layers = classmethod(built)  # type: ignore[method-assign]
        Path.read_text = read_text  # type: ignore[method-assign]
    print(f"threshold {detection[camera].threshold:g} reached detection of {camera}")
    print("functions that received it, in order:")
    for i, where in enumerate(path, 1):
        print(f"  {i:2d}. {where}")
    print("changes of form:")
    for event in events:
        print(f"  - {event}")


if __name__ == "__main__":
    main(Path(sys.argv[1]), *sys.argv[2:3])
