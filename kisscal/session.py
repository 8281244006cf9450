"""Runs a lab session: one stage calling the next, reading and writing through :mod:`kisscal.io`.

The CLI is a thin layer over the functions here; tests call them directly.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

from kisscal.errors import KisscalError, NotBuiltError

Echo = Callable[[str], object]


def _quiet(_: str) -> None:
    return None


def default_walking5_path() -> Path | None:
    """The real walking trial shipped beside the project (``../shared/data/walking5.c3d``)."""
    env = os.environ.get("KISSCAL_WALKING5")
    candidates = [Path(env)] if env else []
    repo = Path(__file__).resolve().parents[1]
    candidates += [
        repo.parent / "shared" / "data" / "walking5.c3d",
        repo / "fixtures" / "walking5.c3d",
    ]
    return next((p for p in candidates if p.is_file()), None)


def synthesise(
    out: Path,
    *,
    seed: int = 1,
    fields: int = 200,
    n_cameras: int = 6,
    n_markers: int = 15,
    blur_px: float | None = None,
    walking5: bool = True,
    force: bool = False,
    n_jobs: int | None = None,
    echo: Echo = _quiet,
) -> Path:
    """Write a synthetic KISS-like session (images, ``session.toml``, ``truth/``) to ``out``.

    The same arguments give byte-identical files. With ``walking5`` the real Vicon trial
    is replayed through the synthetic cameras as trial ``walk5`` when it can be found.
    """
    from kisscal.io.synthetic import load_walking5, write_synthetic_session
    from kisscal.synth.plan import SynthOptions, plan_session
    from kisscal.synth.render import RenderParams

    if n_markers not in (13, 15):
        raise KisscalError(f"--markers must be 13 or 15, got {n_markers}")
    if not 2 <= n_cameras <= 6:
        raise KisscalError(f"--cameras must be between 2 and 6, got {n_cameras}")
    if fields < 10:
        raise KisscalError(f"--fields must be at least 10, got {fields}")
    render = RenderParams() if blur_px is None else RenderParams(blur_px=blur_px)
    options = SynthOptions(
        seed=seed, fields=fields, n_cameras=n_cameras, n_markers=n_markers, render=render
    )
    replay = None
    if walking5:
        path = default_walking5_path()
        if path is None:
            echo("walking5.c3d not found: the real-trial replay (walk5) is skipped")
        else:
            replay = load_walking5(path)
    plan = plan_session(options, replay)
    t0 = time.perf_counter()
    write_synthetic_session(
        Path(out), plan, f"synth-seed{seed}", force=force, n_jobs=n_jobs or os.cpu_count() or 1
    )
    echo(
        f"wrote {out}: {len(plan.rig)} cameras, grid and rod frames, trials "
        f"{', '.join(f'{t} ({m.n_fields} fields)' for t, m in plan.trials.items())}, "
        f"truth/ ({time.perf_counter() - t0:.1f} s)"
    )
    return Path(out)


def demo(out: Path, *, seed: int = 1, echo: Echo = _quiet) -> None:
    """Synthesise a KISS-like session into ``out`` and process it."""
    raise NotBuiltError("demo", "synthetic rig")
