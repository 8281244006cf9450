"""`kisscal demo` prints what summary.json holds; `kisscal batch` runs sessions on Dask;
a trial given as centroid files (hardware-detecting cameras) runs from linearisation on."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from kisscal import session
from kisscal.io.config import load_toml
from kisscal.io.files import read_table, write_table
from tests.session.conftest import copy_of

pytestmark = pytest.mark.slow


def kisscal(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "kisscal", *args],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=cwd,
    )


def test_demo_prints_the_summary(tmp_path: Path) -> None:
    result = kisscal("demo", str(tmp_path / "demo"))
    assert result.returncode == 0, result.stderr[-2000:]
    summary = json.loads((tmp_path / "demo" / "out" / "summary.json").read_text())
    text = result.stderr  # the log; nothing is data
    assert result.stdout == ""
    for cam, entry in summary["cameras"].items():
        row = re.search(rf"^{cam}\s+([\d.]+)\s+([\d.]+)$", text, re.M)
        assert row, cam
        assert float(row[1]) == pytest.approx(entry["grid"]["rms_px"], abs=6e-4)
        assert float(row[2]) == pytest.approx(entry["dlt"]["rms_px"], abs=6e-4)
    walk = summary["truth"]["walk01"]
    line = next(line for line in text.splitlines() if line.startswith("walk01:"))
    assert f"{walk['n_trajectories']} trajectories" in line
    assert f"3D RMSE {walk['rmse_measured_mm']:.2f} mm" in line
    assert walk["rmse_measured_mm"] < 1.0
    assert f"{walk['correctly_labelled']} labelled right" in line
    # trials without a marker set say nothing of labels; nothing is printed as nan
    stick = next(line for line in text.splitlines() if line.startswith("stick:"))
    assert "labelled" not in stick and "stick length error" in stick
    assert "nan" not in text
    # a first run is clean: walk5 is cut to the fields the six KISS cameras see whole
    warnings = [w for w in text.lower().splitlines() if "warning" in w]
    assert not warnings, warnings
    walk5 = summary["truth"]["walk5"]
    assert walk5["coverage"] >= 0.9 and "1 trajectories" not in text
    assert (tmp_path / "demo" / "out" / "report.html").is_file()


def test_batch_runs_sessions_on_a_local_dask_cluster(synthesised: Path, tmp_path: Path) -> None:
    """Two good sessions (copies of the shared one, throw trial alone: the fewest images)
    on the local cluster's two worker processes, and a broken one that fails alone."""
    roots = [copy_of(synthesised, tmp_path / f"s{i}", trials=("throw",)) for i in range(2)]
    broken = copy_of(synthesised, tmp_path / "broken", trials=("throw",))
    (broken / "session.toml").write_text("[session]\nname = 'x'\n")  # no rate_hz, no cameras
    result = kisscal("batch", *map(str, roots), str(broken))
    assert result.returncode == 1, result.stderr[-2000:]
    assert (
        result.stderr.count("ok ") == 2 and "FAILED" in result.stderr and "broken" in result.stderr
    )
    assert "2 of 3 sessions processed" in result.stderr
    for root in roots:
        summary = json.loads((root / "out" / "summary.json").read_text())
        assert list(summary["trials"]) == ["throw"]
        assert summary["trials"]["throw"]["trajectories"] == 1


def test_trial_from_centroid_files(small_session: Path, tmp_path: Path) -> None:
    """The thesis' input: 2D centroids per camera (raw pixels) instead of images."""
    root = tmp_path / "s"
    shutil.copytree(small_session, root, ignore=shutil.ignore_patterns("out"))
    truth = read_table(root / "truth" / "trials" / "stick" / "centroids.csv")
    rng = np.random.default_rng(0)
    config = load_toml(root / "session.toml")
    for cam in [c["id"] for c in config["cameras"]]:
        rows = truth["camera"] == cam
        write_table(
            root / "centroids" / f"{cam}.csv",
            {
                "field": truth["field"][rows].astype(int),
                "x_px": truth["u_px"][rows] + rng.normal(0, 0.02, rows.sum()),
                "y_px": truth["v_px"][rows] + rng.normal(0, 0.02, rows.sum()),
            },
        )
    config["trials"] = [{"name": "stick2d", "centroids": "centroids/{camera}.csv"}]
    (root / "session.toml").write_text(tomli_w.dumps(config))
    session.run(root)
    tr = read_table(root / "out" / "trials" / "stick2d" / "trajectories.csv")
    assert sorted(set(tr["label"])) == ["M1", "M2"]
    from kisscal.synth.evaluate import stick_length_error

    xyz = np.column_stack([tr["x_mm"], tr["y_mm"], tr["z_mm"]])
    mae, sd, n = stick_length_error(tr["field"].astype(int), tr["label"], xyz, tr["status"])
    assert n > 190 and mae < 1.1 and sd < 1.5
