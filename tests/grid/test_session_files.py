"""The grid stage on a session written by ``kisscal synth``: PNG frames in, JSON out,
judged against the session's truth tables (``truth/grid``, ``truth/trials``)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from kisscal.grid import apply_linearisation
from kisscal.io.linearisation import read_linearisation, write_linearisation
from tests.grid.grid_synth import fit_similarity, rms


def _table(path):
    return np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")


@pytest.mark.slow
def test_linearisation_files_correct_the_trial_markers(small_session, tmp_path):
    from kisscal.grid import linearise_frames

    centroids = _table(small_session / "truth" / "trials" / "walk01" / "centroids.csv")
    cameras = sorted(p.name for p in (small_session / "grid").iterdir())
    assert len(cameras) == 6
    for camera in cameras:
        frames = [
            cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
            for p in sorted((small_session / "grid" / camera).glob("*.png"))
        ]
        fit = linearise_frames(frames)
        path = write_linearisation(
            tmp_path / "linearisation" / f"{camera}.json",
            fit.linearisation,
            camera,
            fit.index.missing_rc,
            fit.index.missing_uv,
        )
        doc = json.loads(path.read_text())
        assert doc["dots_used"] == 300 and doc["rms_px"] <= 0.08
        _, lin = read_linearisation(path)

        grid = _table(small_session / "truth" / "grid" / f"{camera}.csv")
        raw = np.column_stack([grid["u_px"], grid["v_px"]])
        ideal = np.column_stack([grid["u_ideal_px"], grid["v_ideal_px"]])
        corrected = apply_linearisation(lin, raw)
        assert rms(fit_similarity(ideal, corrected) - corrected) <= 0.08, camera

        mine = centroids[centroids["camera"] == camera]
        raw = np.column_stack([mine["u_px"], mine["v_px"]])
        ideal = np.column_stack([mine["u_ideal_px"], mine["v_ideal_px"]])
        corrected = apply_linearisation(lin, raw)
        assert rms(fit_similarity(ideal, corrected) - corrected) <= 0.15, camera
