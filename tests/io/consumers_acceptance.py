"""Issue 28: Pose2Sim and aniposelib triangulate kisscal's 2D output with kisscal's exports.

``python -m tests.io.consumers_acceptance [SEED] [--figure PATH] [--session PATH]`` from
the repository root, with a Python that has both tools (see below). A synthetic session
is made and run (or ``--session``'s, kept, made there on the first call); its
calibration is exported with ``kisscal export --to pose2sim`` (Pose2Sim's
``Calib_kisscal.toml``, metres) and ``--to anipose --units m``; then, for every trial,
each tool triangulates the observations of ``points2d.csv`` that kisscal used for each
3D point (grouped by the ``point`` column), with the calibration loaded by its own
reader and its own triangulation, and the result is compared with kisscal's
``points3d.csv``:

* Pose2Sim (``Pose2Sim.common``): ``computeP(calib, undistort=True)`` and the points
  undistorted to ``optim_K`` with ``cv2.undistortPoints`` as ``Pose2Sim.triangulation``
  does with ``undistort_points = true``, then ``weighted_triangulation``, once with
  likelihood 1 (as it comes) and once with the ``weight`` column of ``points2d.csv`` as
  the likelihoods (1 / depth: its algebraic rows become image distances in pixels);
* aniposelib: ``CameraGroup.load``, then ``CameraGroup.triangulate(undistort=True)`` (its
  algebraic DLT in normalised coordinates) and ``CameraGroup.triangulate_optim`` (the same,
  refined by least squares on the reprojection error in pixels), without its temporal
  smoothing (``scale_smooth=0``: the points of a field are not a time series) and with a
  plain squared loss (``reproj_loss="linear"``).

Both tools declare ``opencv-python`` / ``opencv-contrib-python``, which would replace
kisscal's ``opencv-python-headless`` ``cv2`` in the same environment; they are therefore
installed beside it, in a virtual environment that sees kisscal's packages::

    python -m venv --system-site-packages /tmp/kisscal-consumers
    /tmp/kisscal-consumers/bin/pip install --no-deps pose2sim aniposelib
    /tmp/kisscal-consumers/bin/pip install toml tqdm rtoml anytree numba "jax[cpu]"
    /tmp/kisscal-consumers/bin/python -m tests.io.consumers_acceptance
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.metadata
import io
import tempfile
import warnings
from pathlib import Path

import cv2
import numpy as np

from kisscal import session
from kisscal.io.config import load_toml
from kisscal.io.points2d import read_points2d
from kisscal.io.points3d import read_points3d
from kisscal.report.html import figure_png
from kisscal.session.calibrated import current_rig
from kisscal.session.exports import export

#: Issue 28's bar: each tool's 3D points within this distance of kisscal's (mm).
BAR_MM = 0.1
#: The triangulations compared: each tool as it comes, and as points2d.csv's documentation
#: says to use it (Pose2Sim with its ``weight`` column, aniposelib's refinement).
TOOLS = (
    "pose2sim",
    "pose2sim, points2d weights",
    "aniposelib",
    "aniposelib, triangulate_optim",
)


def observations_by_point(
    root: Path, trial: str, cameras: list[str], projected: bool = False
) -> tuple:
    """kisscal's 3D points of a trial, their observations as a dense (camera, point, 2)
    array of raw pixels (NaN: camera not used), cameras in the order given, and the
    observations' ``weight`` column as a (camera, point) array.

    ``projected``: instead of the measured pixels, kisscal's own projection of its 3D
    point into each camera that observed it (2D data without noise: the tools must then
    land on kisscal's points up to the OpenCV model's fit, whatever their method).
    """
    p2 = read_points2d(root / "out" / "trials" / trial / "points2d.csv")
    p3 = read_points3d(root / "out" / "trials" / trial / "points3d.csv")
    used = p2.point >= 0
    column = {c: i for i, c in enumerate(cameras)}
    dense = np.full((len(cameras), len(p3.field), 2), np.nan)
    weight = np.full((len(cameras), len(p3.field)), np.nan)
    cam = np.array([column[c] for c in p2.camera[used]], dtype=np.int64)
    dense[cam, p2.point[used]] = p2.xy_px[used]
    weight[cam, p2.point[used]] = p2.weight[used]
    if projected:
        rig = current_rig(root)
        for i, c in enumerate(cameras):
            seen = np.isfinite(dense[i, :, 0])
            dense[i, seen] = rig.camera(c).project(p3.xyz_mm[seen])
    return p3, dense, weight


def pose2sim_triangulate(
    calib: Path, dense_px: np.ndarray, likelihood: np.ndarray | None = None
) -> np.ndarray:
    """Pose2Sim's triangulation of (camera, point, 2) raw pixels, cameras in the calibration
    file's order: its projection matrices, its undistortion, its weighted DLT (metres).

    ``likelihood`` (camera, point): the weight Pose2Sim gives each camera's rows (its pose
    estimator's likelihood); None: 1 for every camera.
    """
    from Pose2Sim.common import computeP, retrieve_calib_params, weighted_triangulation

    P = computeP(calib, undistort=True)
    params = retrieve_calib_params(calib)
    ideal = np.full_like(dense_px, np.nan)
    for c in range(len(P)):
        seen = np.isfinite(dense_px[c, :, 0])
        pts = dense_px[c, seen].reshape(-1, 1, 2)
        if len(pts):
            ideal[c, seen] = cv2.undistortPoints(
                pts, params["K"][c], params["dist"][c], None, params["optim_K"][c]
            ).reshape(-1, 2)
    if likelihood is None:
        likelihood = np.ones(dense_px.shape[:2])
    out = np.full((dense_px.shape[1], 3), np.nan)
    for k in range(dense_px.shape[1]):  # Pose2Sim's own function works one point at a time
        cams = np.flatnonzero(np.isfinite(ideal[:, k, 0]))
        Ps = [P[c] for c in cams]
        q = weighted_triangulation(Ps, ideal[cams, k, 0], ideal[cams, k, 1], likelihood[cams, k])
        out[k] = q[:3]
    return out


def anipose_triangulate(calib: Path, dense_px: np.ndarray, optim: bool = False) -> np.ndarray:
    """aniposelib's triangulation (file units) of (camera, point, 2) raw pixels, cameras in
    the order of ``CameraGroup.load`` (its tables sorted by name): ``triangulate``, or with
    ``optim`` ``triangulate_optim`` without temporal smoothing and with a squared loss."""
    from aniposelib.cameras import CameraGroup

    group = CameraGroup.load(str(calib))
    with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numba's object-mode notes on aniposelib's code
        if not optim:
            return np.asarray(group.triangulate(dense_px, undistort=True), dtype=float)
        # (camera, frame, joint, 2): each point a frame of one joint
        xyz = group.triangulate_optim(dense_px[:, :, None], scale_smooth=0, reproj_loss="linear")
    return np.asarray(xyz, dtype=float).reshape(-1, 3)


def compare(root: Path) -> dict[str, dict[str, np.ndarray]]:
    """Per trial and tool, the 3D distance (mm) of each point to kisscal's."""
    out = root / "out"
    quiet = lambda *_: None  # noqa: E731
    p2s = export(root, "pose2sim", echo=quiet)[0]
    ani = export(root, "anipose", out / "cameras_m.toml", echo=quiet, units="m")[0]
    p2s_cams = list(load_toml(p2s)["metadata"]["cameras"].values())  # cam_01... -> ids
    from aniposelib.cameras import CameraGroup

    ani_cams = CameraGroup.load(str(ani)).get_names()
    result: dict[str, dict[str, np.ndarray]] = {}
    trials = [t.name for t in sorted((out / "trials").iterdir()) if (t / "points2d.csv").is_file()]
    for trial, projected in [(t, False) for t in trials] + [(t, True) for t in trials]:
        p3, dense, weight = observations_by_point(root, trial, p2s_cams, projected)

        def mm(xyz_m: np.ndarray, p3=p3) -> np.ndarray:
            return np.linalg.norm(xyz_m * 1000 - p3.xyz_mm, axis=1)

        by_tool = {
            "pose2sim": mm(pose2sim_triangulate(p2s, dense)),
            "pose2sim, points2d weights": mm(pose2sim_triangulate(p2s, dense, weight)),
        }
        _, dense, _ = observations_by_point(root, trial, ani_cams, projected)
        by_tool["aniposelib"] = mm(anipose_triangulate(ani, dense))
        by_tool["aniposelib, triangulate_optim"] = mm(anipose_triangulate(ani, dense, True))
        name = f"{trial} (kisscal's projection)" if projected else trial
        result[name] = {**by_tool, "rms_px": p3.rms_px}
    return result


def table(result: dict[str, dict[str, np.ndarray]]) -> list[str]:
    lines = [
        f"| trial | points | tool | median (mm) | 99th pct (mm) | max (mm) | within {BAR_MM} mm |",
        "|---|---|---|---|---|---|---|",
    ]
    for trial, by_tool in result.items():
        for tool in TOOLS:
            d = by_tool[tool]
            lines.append(
                f"| {trial} | {len(d)} | {tool} | {np.median(d):.4f} | "
                f"{np.percentile(d, 99):.4f} | {d.max():.4f} | {np.mean(d <= BAR_MM):.1%} |"
            )
    return lines


def figure(result: dict[str, dict[str, np.ndarray]], path: Path) -> None:
    """Distance to kisscal's points against kisscal's reprojection RMS, per triangulation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharey=True, constrained_layout=True)
    for ax, tool in zip(axes.ravel(), TOOLS, strict=True):
        for trial, by_tool in result.items():
            if "projection" in trial:
                continue
            ax.scatter(by_tool["rms_px"], by_tool[tool], s=4, alpha=0.6, label=trial)
        ax.axhline(BAR_MM, color="k", lw=0.8, ls="--")
        ax.set_yscale("log")
        if ax in axes[1]:
            ax.set_xlabel("kisscal reprojection rms of the point (px)")
        name, _, weights = tool.partition(", ")
        package = "Pose2Sim" if name == "pose2sim" else name
        ax.set_title(f"{package} {importlib.metadata.version(name)}\n{weights or 'as it is'}")
    for ax in axes[:, 0]:
        ax.set_ylabel("3D distance to kisscal's point (mm)")
    axes[0, 0].legend(markerscale=3, fontsize=8)
    path.write_bytes(figure_png(fig))  # kisscal's figures' palette PNG: a quarter the size
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("seed", nargs="?", type=int, default=3)
    parser.add_argument("--fields", type=int, default=100)
    parser.add_argument("--figure", type=Path, default=Path("consumers.png"))
    parser.add_argument(
        "--session", type=Path, help="a session made and run here before (kept; default: temp)"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.session or Path(tmp) / "s"
        if not (root / "out" / "summary.json").is_file():
            session.synthesise(root, seed=args.seed, fields=args.fields, walking5=False, n_jobs=1)
            session.run(root)
        result = compare(root)
        figure(result, args.figure)
    print("\n".join(table(result)))
    for tool in TOOLS:
        worst = max(float(d[tool].max()) for d in result.values())
        verdict = "met" if worst <= BAR_MM else "NOT met"
        print(f"{tool}: largest distance {worst:.4f} mm; bar {BAR_MM} mm {verdict}")
    print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
