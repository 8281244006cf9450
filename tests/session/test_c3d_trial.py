"""``[[trials]] c3d``: 3D points from a C3D file, re-tracked from scratch.

walking5.c3d's physical markers (names ending JC are computed joint centres, dropped)
are written to a C3D whose channels are shuffled in every frame and named P1, P2, ...:
neither channel order nor label carries identity. The session (C3D trials only: nothing
to calibrate) must give tracks that each follow one true marker.
"""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np
import pytest
from scipy.spatial import cKDTree

from kisscal import session
from kisscal.errors import KisscalError
from kisscal.io.c3d import read_c3d_points
from kisscal.io.trajectories import read_trajectories_csv
from kisscal.session.synth import default_walking5_path

WALKING5 = default_walking5_path()
pytestmark = pytest.mark.skipif(WALKING5 is None, reason="walking5.c3d not found")


def write_shuffled_c3d(path: Path, xyz: np.ndarray, rate_hz: float, seed: int = 0) -> None:
    """Each frame's valid points in random channels P1..Pn (NaN elsewhere)."""
    rng = np.random.default_rng(seed)
    n_frames, n_markers, _ = xyz.shape
    channels = np.full_like(xyz, np.nan)
    for f in range(n_frames):
        valid = np.flatnonzero(np.isfinite(xyz[f, :, 0]))
        channels[f, rng.permutation(n_markers)[: len(valid)]] = xyz[f, valid]
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [rate_hz]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(f"P{i + 1}" for i in range(n_markers))
    c.add_parameter("POINT", "UNITS", "mm")
    points = np.ones((4, n_markers, n_frames))
    points[:3] = channels.transpose(2, 1, 0)
    c["data"]["points"] = points
    c.write(str(path))


def c3d_session(root: Path, rate_hz: float, c3d: str = "walk.c3d") -> Path:
    root.mkdir(parents=True, exist_ok=True)
    (root / "session.toml").write_text(
        f'[session]\nname = "c3d"\nrate_hz = {rate_hz}\n\n'
        f'[[trials]]\nname = "walk"\nc3d = "{c3d}"\n'
    )
    return root


@pytest.fixture(scope="module")
def walking5_markers() -> tuple[np.ndarray, float]:
    labels, xyz, rate = read_c3d_points(WALKING5)
    keep = [i for i, name in enumerate(labels) if not name.endswith("JC")]
    return xyz[:, keep], rate


def true_identity(tracks, truth: np.ndarray) -> np.ndarray:
    """The true marker of each measured sample (-2: no true marker within 0.01 mm)."""
    ident = np.full(len(tracks.field), -1)
    measured = tracks.status == 0
    for f in np.unique(tracks.field[measured]):
        rows = np.flatnonzero(measured & (tracks.field == f))
        idx = np.flatnonzero(np.isfinite(truth[f, :, 0]))
        d, j = cKDTree(truth[f, idx]).query(tracks.xyz_mm[rows])
        ident[rows] = np.where(d < 0.01, idx[j], -2)
    return ident


def test_shuffled_anonymous_c3d_comes_back_without_identity_switches(
    walking5_markers, tmp_path: Path
) -> None:
    xyz, rate = walking5_markers
    root = c3d_session(tmp_path / "s", rate)
    write_shuffled_c3d(root / "walk.c3d", xyz, rate)
    session.run(root)
    tracks = read_trajectories_csv(root / "out" / "trials" / "walk" / "trajectories.csv")
    ident = true_identity(tracks, xyz)
    measured = tracks.status == 0
    assert not np.any(ident[measured] == -2)  # every measured sample is a true one
    # every valid sample of the file comes out (short pieces kept: no ghosts in a C3D)
    assert measured.sum() == np.isfinite(xyz[..., 0]).sum()
    switches, pieces = 0, {}
    for t in np.unique(tracks.track):
        rows = np.flatnonzero((tracks.track == t) & measured)
        ids = ident[rows][np.argsort(tracks.field[rows])]
        switches += int(np.sum(ids[1:] != ids[:-1]))
        pieces.setdefault(int(ids[0]), []).append(int(t))
    assert switches == 0
    # a marker comes back in one long track, or splits where the source itself jumps
    # (walking5 has single-frame jumps of 25-55 mm, several times a marker's step) or
    # after a gap; pieces shorter than the tracker's minimum length (isolated samples
    # around gaps) are kept apart, unnamed
    speed = np.linalg.norm(np.diff(xyz, axis=0), axis=2)
    for marker, tracks_of_marker in pieces.items():
        long = [t for t in tracks_of_marker if (measured & (tracks.track == t)).sum() >= 10]
        starts = [int(tracks.field[tracks.track == t].min()) for t in long[1:]]
        assert all(not speed[s - 1, marker] <= 20.0 for s in starts), marker


def test_c3d_trial_rate_must_match_the_session(walking5_markers, tmp_path: Path) -> None:
    xyz, rate = walking5_markers
    root = c3d_session(tmp_path / "s", rate / 2)
    write_shuffled_c3d(root / "walk.c3d", xyz[:50], rate)
    with pytest.raises(KisscalError, match="rate_hz"):
        session.reconstruct(root, "walk")


def test_a_file_without_points_is_said_so_not_blamed_on_rate_hz(tmp_path: Path) -> None:
    """A force-plate file (Kistler's in the ezc3d test files) holds analog data only and
    a point rate of 0: validate and run say the file holds no 3D points, rather than
    asking whether rate_hz = 100 is right."""
    root = c3d_session(tmp_path / "s", 100.0)
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [0.0]
    c["parameters"]["ANALOG"]["RATE"]["value"] = [1000.0]
    c["parameters"]["ANALOG"]["LABELS"]["value"] = ["Fz"]
    c["parameters"]["ANALOG"]["USED"]["value"] = [1]
    c["data"]["points"] = np.zeros((4, 0, 50))
    c["data"]["analogs"] = np.random.default_rng(0).random((1, 1, 50))
    c.write(str(root / "walk.c3d"))
    problems = [p.message for p in session.validate(root)]
    assert any("holds no 3D points" in p for p in problems), problems
    assert not any("rate_hz" in p for p in problems)
    with pytest.raises(KisscalError, match="holds no 3D points"):
        session.reconstruct(root, "walk")


def test_a_real_two_frame_qualisys_file_comes_out_whole_with_its_frame_numbers(tmp_path):
    """FP_Type3.c3d (QTM, 2 frames of 34 markers, frames 1166-1167): a session of C3D trials
    without [[cameras]]; every sample comes out (unlabelled: two frames cannot be
    tracked) and trajectories.c3d keeps the file's frame numbers."""
    real = Path(__file__).resolve().parents[2] / "fixtures" / "real" / "c3d" / "FP_Type3.c3d"
    root = c3d_session(tmp_path / "s", 250.0, c3d="fp.c3d")
    (root / "fp.c3d").write_bytes(real.read_bytes())
    session.run(root)
    out = root / "out" / "trials" / "walk"
    tracks = read_trajectories_csv(out / "trajectories.csv")
    source = read_c3d_points(real)[1]
    assert (tracks.status == 0).sum() == np.isfinite(source[..., 0]).sum() == 68
    assert len(np.unique(tracks.track)) == 34
    c = ezc3d.c3d(str(out / "trajectories.c3d"))
    assert c["header"]["points"]["first_frame"] == 1165  # ezc3d counts from 0: frame 1166
    assert c["data"]["points"].shape[1:] == (34, 2)
    assert list(c["parameters"]["TRIAL"]["ACTUAL_START_FIELD"]["value"]) == [1166, 0]


def test_model_outputs_are_left_out_and_said(walking5_markers, tmp_path: Path) -> None:
    """A file as Nexus saves it: markers plus model outputs stored as points
    (POINT:ANGLES). Only the markers become 3D points; the log and recon.json name the
    outputs left out."""
    import json

    xyz, rate = walking5_markers
    xyz = xyz[400:440, :5]
    root = c3d_session(tmp_path / "s", rate)
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["POINT"]["LABELS"]["value"] = ["A", "B", "C", "D", "E", "LHipAngles"]
    c.add_parameter("POINT", "UNITS", "mm")
    c.add_parameter("POINT", "ANGLES", ["LHipAngles"])
    points = np.ones((4, 6, 40))
    points[:3, :5] = xyz.transpose(2, 1, 0)
    points[:3, 5] = 10.0  # angles in degrees, far from any marker
    c["data"]["points"] = points
    c.write(str(root / "walk.c3d"))
    said: list[str] = []
    pts = session.reconstruct(root, "walk", echo=said.append)
    assert len(pts.field) == np.isfinite(xyz[..., 0]).sum()
    assert any("left out 1 model outputs" in line and "LHipAngles" in line for line in said)
    recon = json.loads((root / "out" / "trials" / "walk" / "recon.json").read_text())
    assert recon["excluded_model_outputs"] == ["LHipAngles"] and recon["fields"] == 40
