"""The catalogue of bad inputs: what a user did, what kisscal says, exit code, what is kept.

Each :class:`Case` breaks a copy of a good, processed session in one way and runs one
command on it. ``tests/session/test_catalogue.py`` runs every case; ``docs/bad-inputs.md``
is generated from this list (``python -m tests.session.catalogue > docs/bad-inputs.md``)
and a test checks the page is current.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import tomli_w

from kisscal.io.config import load_toml

Setup = Callable[[Path], None]


@dataclass(frozen=True)
class Case:
    """One bad input: ``setup`` breaks the session at the path it is given."""

    id: str
    stage: str
    did: str
    setup: Setup
    args: tuple[str, ...]  # the command; "S" stands for the session folder
    says: tuple[str, ...]  # words of the one-line message
    exit_code: int = 2
    kept: str = "every earlier output, byte for byte"
    log: tuple[str, ...] = field(default=())  # words expected in the log (stderr) instead
    fault: str | None = None  # an OS error injected in-process: "erofs" or "enospc"


# ------------------------------------------------------------------------ setups


def toml_edit(change: Callable[[dict], None]) -> Setup:
    def setup(root: Path) -> None:
        data = load_toml(root / "session.toml")
        change(data)
        (root / "session.toml").write_text(tomli_w.dumps(data))

    return setup


def nothing(_root: Path) -> None:
    return None


def frame(root: Path, trial: str = "walk01", cam: str = "cam2", k: int = 5) -> Path:
    return sorted((root / "trials" / trial / cam).glob("*.png"))[k]


def write_text(relative: str, text: str | bytes) -> Setup:
    def setup(root: Path) -> None:
        path = root / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(text.encode() if isinstance(text, str) else text)

    return setup


def corrupt_png(root: Path) -> None:
    frame(root).write_bytes(b"\x89PNG\r\n\x1a\nbroken")


def truncated_png(root: Path) -> None:
    path = frame(root)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def float_tiff(root: Path) -> None:
    """A 32-bit float TIFF among PNG frames (the trial's pattern takes every file)."""
    path = frame(root)
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE).astype(np.float32)
    path.unlink()
    cv2.imwrite(str(path.with_suffix(".tif")), image)
    toml_edit(_any_frame_file)(root)


def _any_frame_file(data: dict) -> None:
    data["trials"][0]["images"] = "trials/walk01/{camera}/*"


def wrong_size_frame(root: Path) -> None:
    path = frame(root)
    cv2.imwrite(str(path), np.zeros((480, 640), np.uint8))


def late_small_frame(root: Path) -> None:
    """A 320 x 240 frame late in a camera's frames (validate once read the first only)."""
    cv2.imwrite(str(frame(root, k=15)), np.zeros((240, 320), np.uint8))


def jpeg_in_png(root: Path) -> None:
    """JPEG data saved under the .png names of one camera's frames."""
    for path in sorted((root / "trials" / "walk01" / "cam2").glob("*.png")):
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        path.write_bytes(cv2.imencode(".jpg", image)[1].tobytes())


def renamed_camera_folders(root: Path) -> None:
    """Every camera folder named after the camera's position, not its id."""
    for cam_folder in sorted(root.glob("*/cam?")) + sorted(root.glob("trials/*/cam?")):
        cam_folder.rename(
            cam_folder.with_name(
                "left" if cam_folder.name == "cam1" else f"view{cam_folder.name[-1]}"
            )
        )


def unfilled_rods(data: dict) -> None:
    for rod in data["rods"]["rod"]:
        rod["points_mm"] = []


def absolute_pattern(root: Path) -> None:
    toml_edit(lambda d: d["trials"][0].update(images=f"{root}/trials/walk01/{{camera}}/*.png"))(
        root
    )


def c3d_at_rate(rate_hz: float) -> Setup:
    """A C3D trial ``old`` recorded at ``rate_hz`` with two markers in every frame."""

    def setup(root: Path) -> None:
        import ezc3d

        c = ezc3d.c3d()
        c["parameters"]["POINT"]["RATE"]["value"] = [rate_hz]
        c["parameters"]["POINT"]["LABELS"]["value"] = ("A", "B")
        points = np.ones((4, 2, 10))
        points[:3] = np.random.default_rng(1).uniform(-500, 500, (3, 2, 10))
        c["data"]["points"] = points
        c.write(str(root / "old.c3d"))
        toml_edit(lambda d: d["trials"].append({"name": "old", "c3d": "old.c3d"}))(root)

    return setup


def drop_frame(root: Path) -> None:
    frame(root, cam="cam3", k=7).unlink()


def empty_trial(root: Path) -> None:
    for cam in (root / "trials" / "stick").iterdir():
        for f in cam.glob("*.png"):
            f.unlink()


def missing_camera_folder(root: Path) -> None:
    shutil.rmtree(root / "trials" / "stick" / "cam4")


def centroid_trial(text_by_camera: Callable[[str], str]) -> Setup:
    def setup(root: Path) -> None:
        data = load_toml(root / "session.toml")
        for cam in ("cam1", "cam2", "cam3", "cam4"):
            (root / "centroids").mkdir(exist_ok=True)
            (root / "centroids" / f"{cam}.csv").write_text(text_by_camera(cam))
        data["trials"] = [{"name": "static", "centroids": "centroids/{camera}.csv"}]
        (root / "session.toml").write_text(tomli_w.dumps(data))

    return setup


GOOD_ROWS = "field,x_px,y_px\n0,100.5,80.25\n0,300.0,120.0\n"


def static_target(root: Path) -> None:
    """A one-field trial: 200 points of a static target, as each camera's raw centroids."""
    import json

    from tests.synth.truth_cameras import camera_from_truth

    rng = np.random.default_rng(7)
    grid = np.stack(np.meshgrid(*(np.linspace(-0.8, 0.8, k) for k in (8, 5, 5))), -1)
    xyz = grid.reshape(-1, 3) * [1000.0, 500.0, 800.0] + [0.0, 0.0, 1000.0]
    xyz += rng.normal(0.0, 25.0, xyz.shape)  # a hand-built target, not a perfect lattice
    cams = json.loads((root / "truth" / "cameras.json").read_text())["cameras"]
    text = {}
    for cam in map(camera_from_truth, cams):
        uv = cam.project(xyz)
        text[cam.id] = "field,x_px,y_px\n" + "".join(f"0,{u:.3f},{v:.3f}\n" for u, v in uv)
    centroid_trial(text.__getitem__)(root)


def two_cameras(root: Path) -> None:
    toml_edit(lambda data: data.update(cameras=data["cameras"][:2]))(root)


def blank_trial(root: Path) -> None:
    """Every frame of walk01 black: a trial in which no marker (and no LED) is seen."""
    for path in (root / "trials" / "walk01").rglob("*.png"):
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        cv2.imwrite(str(path), np.zeros_like(image))


def cluttered_rod_frame(root: Path) -> None:
    """1300 marker-like dots over one rod frame of cam2 (a reflective backdrop, a sensor
    gone wrong): far too many blobs to find the rods among them."""
    path = sorted((root / "rods" / "cam2").glob("*.png"))[0]
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    rng = np.random.default_rng(13)
    h, w = image.shape
    for u, v in zip(rng.integers(3, w - 3, 1300), rng.integers(3, h - 3, 1300), strict=True):
        cv2.circle(image, (int(u), int(v)), 2, 255, -1)
    cv2.imwrite(str(path), image)


def control_points(rows: str) -> Setup:
    def setup(root: Path) -> None:
        data = load_toml(root / "session.toml")
        del data["rods"]
        data["calibration"] = {"points": "cp/{camera}.csv"}
        for cam in ("cam1", "cam2", "cam3", "cam4"):
            (root / "cp").mkdir(exist_ok=True)
            (root / "cp" / f"{cam}.csv").write_text("u_px,v_px,x_mm,y_mm,z_mm\n" + rows)
        (root / "session.toml").write_text(tomli_w.dumps(data))

    return setup


def out_is_a_file(root: Path) -> None:
    shutil.rmtree(root / "out")
    (root / "out").write_text("not a folder")


def hide_rod_markers(root: Path) -> None:
    """Black out two markers of rod R1 in every rod frame of cam2."""
    truth = np.genfromtxt(
        root / "truth" / "rods" / "cam2.csv",
        delimiter=",",
        names=True,
        dtype=None,
        encoding="utf-8",
    )
    hidden = truth[(truth["rod"] == "R1") & (truth["index"] >= 5)]
    for path in sorted((root / "rods" / "cam2").glob("*.png")):
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        for u, v in zip(hidden["u_px"], hidden["v_px"], strict=True):
            cv2.ellipse(image, (round(u), round(v)), (12, 7), 0, 0, 360, 0, -1)
        cv2.imwrite(str(path), image)


def bom_crlf(root: Path) -> None:
    text = (root / "session.toml").read_text().replace("\n", "\r\n")
    (root / "session.toml").write_bytes(b"\xef\xbb\xbf" + text.encode())


def _rods_flat(data: dict) -> None:
    for rod in data["rods"]["rod"]:
        for p in rod["points_mm"]:
            p[2] = 0.0


def _first_camera_size(data: dict) -> None:
    data["cameras"][0]["size"] = [800, 600]


def _duplicate_camera(data: dict) -> None:
    data["cameras"][1]["id"] = "cam1"


def _param(section: str, key: str, value: object) -> Callable[[dict], None]:
    def change(data: dict) -> None:
        data.setdefault(section, {})[key] = value

    return change


def _wand_one_marker(data: dict) -> None:
    data["wand"] = {"trial": "walk01", "markers_mm": [500.0]}


def _rename_table(data: dict) -> None:
    data["sesion"] = data.pop("session")


def wand_trial(**options: object) -> Setup:
    """A wand trial (centroid files from the true cameras) and ``[wand]``."""

    def setup(root: Path) -> None:
        from tests.session.wand_session import add_wand_trial

        add_wand_trial(root, **options)  # type: ignore[arg-type]

    return setup


def imported_cameras(change: Callable[[dict], None]) -> Setup:
    """The session calibrated from its own exported cameras.toml, broken by ``change``."""

    def setup(root: Path) -> None:
        doc = load_toml(root / "out" / "cameras.toml")
        change(doc)
        (root / "cameras.toml").write_text(tomli_w.dumps(doc))
        data = load_toml(root / "session.toml")
        del data["rods"], data["grid"]
        data["calibration"] = {"cameras": "cameras.toml"}
        (root / "session.toml").write_text(tomli_w.dumps(data))

    return setup


def wand_and_axes_hidden(root: Path) -> None:
    """Wand and axes alone; one axes marker blacked out in cam2's axes images."""
    from tests.session.wand_session import add_axes, add_wand_trial

    add_wand_trial(root)
    add_axes(root, hide_in="cam2")


def contradicting_seeds(root: Path) -> None:
    """A target session calibrated once, then two of cam2's seeds given each other's names."""
    from kisscal import session
    from kisscal.io.files import read_table, write_table

    shutil.rmtree(root)
    session.synthesise_target(root, "stepped", seed=3)
    session.calibrate(root)
    path = root / "calibration" / "cam2_seeds.csv"
    seeds = read_table(path, numeric=("u_px", "v_px", "x_mm", "y_mm", "z_mm"))
    for key in ("x_mm", "y_mm", "z_mm"):
        seeds[key][[1, 4]] = seeds[key][[4, 1]]
    write_table(path, seeds)


def three_seeds(root: Path) -> None:
    """A target session whose cam2 seeds file keeps only its first three clicks."""
    from kisscal import session

    shutil.rmtree(root)
    session.synthesise_target(root, "stepped", seed=3)
    path = root / "calibration" / "cam2_seeds.csv"
    path.write_text("\n".join(path.read_text().splitlines()[:4]) + "\n")


def numbered_frames(root: Path) -> None:
    """A trial's frames named as particle-tracking tools name them (``cam1.10000``, no
    suffix), with a pattern that asks for ``.png`` files."""
    (root / "numbered").mkdir()
    frame = cv2.imencode(".png", np.zeros((291, 752), np.uint8))[1].tobytes()
    for cam in ("cam1", "cam2", "cam3", "cam4"):
        for i in range(3):
            (root / "numbered" / f"{cam}.{10000 + i}").write_bytes(frame)
    data = load_toml(root / "session.toml")
    data["trials"].append({"name": "ptv", "images": "numbered/{camera}.png"})
    (root / "session.toml").write_text(tomli_w.dumps(data))


def dltdv_rows(n_rows: int) -> Setup:
    def setup(root: Path) -> None:
        rows = (root / "out" / "dlt" / "dltdv.csv").read_text().splitlines()[:n_rows]
        (root / "coefs.csv").write_text("\n".join(rows) + "\n")
        data = load_toml(root / "session.toml")
        del data["rods"]
        data["calibration"] = {"dlt": "coefs.csv"}
        (root / "session.toml").write_text(tomli_w.dumps(data))

    return setup


def empty_c3d(root: Path) -> None:
    import ezc3d

    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [50.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = ("A", "B")
    c["data"]["points"] = np.full((4, 2, 10), np.nan)
    c.write(str(root / "empty.c3d"))
    data = load_toml(root / "session.toml")
    data["trials"].append({"name": "old", "c3d": "empty.c3d"})
    (root / "session.toml").write_text(tomli_w.dumps(data))


def short_video(root: Path) -> None:
    """One lossless video per camera, cam2's two frames shorter than the others'."""
    (root / "video").mkdir()
    for cam in ("cam1", "cam2", "cam3", "cam4"):
        fourcc = cv2.VideoWriter_fourcc(*"FFV1")
        writer = cv2.VideoWriter(str(root / "video" / f"{cam}.avi"), fourcc, 25, (752, 291), False)
        for _ in range(8 if cam == "cam2" else 10):
            writer.write(np.zeros((291, 752), np.uint8))
        writer.release()
    data = load_toml(root / "session.toml")
    data["trials"].append({"name": "vid", "video": "video/{camera}.avi"})
    (root / "session.toml").write_text(tomli_w.dumps(data))


# ------------------------------------------------------------------------- cases

CASES: tuple[Case, ...] = (
    Case(
        "missing-folder",
        "session",
        "named a session folder that does not exist",
        nothing,
        ("run", "S/typo"),
        ("typo", "session folder not found"),
        kept="nothing is created",
    ),
    Case(
        "no-session-toml",
        "session",
        "ran a folder without session.toml",
        write_text("other/x.txt", "x"),
        ("run", "S/other"),
        ("session.toml", "file not found"),
        kept="nothing is created",
    ),
    Case(
        "not-toml",
        "session",
        "saved session.toml with a syntax error",
        write_text("session.toml", "[session\nname = 1"),
        ("validate", "S"),
        ("not valid TOML",),
    ),
    Case(
        "bom-crlf",
        "session",
        "saved session.toml in Notepad (byte-order mark, CRLF)",
        bom_crlf,
        ("validate", "S"),
        (),
        exit_code=0,
        log=("every input is present",),
    ),
    Case(
        "misspelt-table",
        "session",
        "wrote [sesion] for [session]",
        toml_edit(_rename_table),
        ("validate", "S"),
        ("unknown key", "did you mean 'session'"),
    ),
    Case(
        "misspelt-parameter",
        "session",
        "wrote treshold in [detection]",
        toml_edit(_param("detection", "treshold", 50)),
        ("run", "S"),
        ("treshold", "did you mean 'threshold'"),
    ),
    Case(
        "absurd-parameter",
        "session",
        "set a negative Kalman process noise",
        toml_edit(_param("tracking", "pnc", -1.0)),
        ("run", "S"),
        ("[tracking]", "pnc", "> 0"),
    ),
    Case(
        "duplicate-camera",
        "session",
        "gave two cameras the same id",
        toml_edit(_duplicate_camera),
        ("validate", "S"),
        ("camera ids must be unique", "cam1"),
    ),
    Case(
        "wand-one-marker",
        "session",
        "described a wand with one marker",
        toml_edit(_wand_one_marker),
        ("validate", "S"),
        ("wand.markers_mm", "2 or more"),
    ),
    Case(
        "coplanar-rods",
        "session",
        "surveyed every rod marker at the same height",
        toml_edit(_rods_flat),
        ("calibrate", "S"),
        ("coplanar",),
    ),
    Case(
        "size-mismatch",
        "session",
        "gave a camera size that its images do not have",
        toml_edit(_first_camera_size),
        ("run", "S"),
        ("cam1", "752 x 291", "800 x 600"),
        kept="every earlier output; nothing is processed",
    ),
    Case(
        "out-is-a-file",
        "session",
        "left a file named out in the session folder",
        out_is_a_file,
        ("run", "S"),
        ("cannot write the output folder",),
        kept="nothing is written",
    ),
    Case(
        "read-only-disk",
        "session",
        "ran a session on a read-only disk (simulated)",
        nothing,
        ("run", "S"),
        ("cannot write the output folder", "Read-only file system"),
        fault="erofs",
        kept="nothing is written",
    ),
    Case(
        "disk-full",
        "session",
        "filled the disk while outputs were written (simulated)",
        nothing,
        ("track", "S", "walk01"),
        ("No space left on device",),
        fault="enospc",
        kept="every earlier output, byte for byte; no partial file",
    ),
    Case(
        "frame-of-other-size",
        "detection",
        "put a 640 x 480 frame among 752 x 291 frames",
        wrong_size_frame,
        ("reconstruct", "S", "walk01"),
        ("640 x 480", "752 x 291", "cam2"),
    ),
    Case(
        "corrupt-png",
        "detection",
        "left a corrupt PNG among the frames",
        corrupt_png,
        ("reconstruct", "S", "walk01"),
        ("000005.png", "not a readable image"),
    ),
    Case(
        "truncated-png",
        "detection",
        "copied a frame that was cut short",
        truncated_png,
        ("reconstruct", "S", "walk01"),
        ("000005.png",),
    ),
    Case(
        "float-tiff",
        "detection",
        "exported a frame as 32-bit floating point TIFF",
        float_tiff,
        ("reconstruct", "S", "walk01"),
        ("000005.tif", "unsupported pixel type"),
    ),
    Case(
        "dropped-frame",
        "reconstruction",
        "lost one frame of one camera",
        drop_frame,
        ("reconstruct", "S", "walk01"),
        ("different numbers of frames", "cam3: 19"),
    ),
    Case(
        "empty-trial",
        "session",
        "left one trial's folders empty (one of three trials)",
        empty_trial,
        ("run", "S"),
        ("1 of 3 trials failed", "stick"),
        kept="the other trials' outputs, complete",
    ),
    Case(
        "missing-camera-folder",
        "session",
        "forgot one camera's folder of a trial",
        missing_camera_folder,
        ("run", "S"),
        ("1 of 3 trials failed", "stick", "cam4"),
        kept="the other trials' outputs, complete",
    ),
    Case(
        "centroids-missing-column",
        "reconstruction",
        "gave a centroid file without y_px",
        centroid_trial(lambda c: "field,x_px\n0,1\n"),
        ("reconstruct", "S", "static"),
        ("missing column", "y_px"),
    ),
    Case(
        "centroids-nan",
        "reconstruction",
        "gave a centroid file with an empty centroid",
        centroid_trial(lambda c: GOOD_ROWS + "1,,5\n"),
        ("reconstruct", "S", "static"),
        ("row 4", "not a number"),
    ),
    Case(
        "centroids-off-image",
        "reconstruction",
        "gave a centroid outside the image",
        centroid_trial(lambda c: GOOD_ROWS + "1,900,5\n"),
        ("reconstruct", "S", "static"),
        ("outside the 752 x 291 pixel image",),
    ),
    Case(
        "centroids-text",
        "reconstruction",
        "gave text in a number column",
        centroid_trial(lambda c: GOOD_ROWS + "1,abc,5\n"),
        ("reconstruct", "S", "static"),
        ("line 4", "x_px must be a number"),
    ),
    Case(
        "centroids-negative-field",
        "reconstruction",
        "numbered fields from -1",
        centroid_trial(lambda c: "field,x_px,y_px\n-1,5,5\n"),
        ("reconstruct", "S", "static"),
        ("field numbers must be 0 or more",),
    ),
    Case(
        "one-field-trial",
        "reconstruction",
        "gave a static target of 200 points as one field of centroids",
        static_target,
        ("reconstruct", "S", "static"),
        (),
        exit_code=0,
        log=(
            "reconstruct static: 200 points in 1 fields",
            "stationary filter not applied",
            "a point that lies at a camera's centre is that camera's ring",
        ),
        kept="every output; all 200 points are reconstructed",
    ),
    Case(
        "blank-trial",
        "reconstruction",
        "recorded a trial of blank frames (no marker in view)",
        blank_trial,
        ("run", "S"),
        (),
        exit_code=0,
        log=("warning: walk01: no 3D points in 20 fields", "empty files written (20 fields)"),
        kept="every output; walk01 gets a header-only CSV and C3D/TRC files without points",
    ),
    Case(
        "two-cameras",
        "reconstruction",
        "ran a session with two cameras only",
        two_cameras,
        ("run", "S"),
        (),
        exit_code=0,
        log=("by 2 cameras",),
        kept="every output; markers seen by both cameras are reconstructed",
    ),
    Case(
        "cluttered-rod-frame",
        "calibration",
        "left 1300 bright dots in a rod frame",
        cluttered_rod_frame,
        ("calibrate", "S"),
        ("camera cam2", "blobs in the rod image, too many to find the rods"),
    ),
    Case(
        "control-points-coplanar",
        "calibration",
        "gave control points all on the floor",
        control_points(
            "".join(f"{10 + i * 7},{20 + i * 3},{i * 100},{(i * 37) % 200},0\n" for i in range(8))
        ),
        ("calibrate", "S"),
        ("coplanar",),
    ),
    Case(
        "control-points-too-few",
        "calibration",
        "gave 5 control points",
        control_points("1,2,0,0,0\n3,4,100,0,5\n5,6,0,100,9\n7,8,100,100,0\n9,9,50,50,300\n"),
        ("calibrate", "S"),
        ("at least 6",),
    ),
    Case(
        "rod-half-hidden",
        "calibration",
        "hid two of a rod's six markers from one camera",
        hide_rod_markers,
        ("calibrate", "S"),
        (),
        exit_code=0,
        log=("calibrate cam2", "18 rod markers", "missing R1.1"),
        kept="that camera is calibrated on the other rods; the output names the missing markers",
    ),
    Case(
        "wand-in-one-camera-at-a-time",
        "calibration",
        "waved the wand where only one camera at a time saw it",
        wand_trial(cameras_at_once=1),
        ("calibrate", "S"),
        ("wand calibration", "two or more cameras at once in 0 fields", "at least 20"),
    ),
    Case(
        "wand-length-off",
        "calibration",
        "gave a wand length 10 % longer than the wand",
        wand_trial(stated_mm=(0.0, 209.0, 550.0)),
        ("calibrate", "S"),
        ("[wand] markers_mm", "550 mm apart", "the rods' calibration measures", "fields, -9."),
    ),
    Case(
        "axes-marker-hidden",
        "calibration",
        "hid one axes marker from one camera (wand and axes, no rods)",
        wand_and_axes_hidden,
        ("calibrate", "S"),
        (),
        exit_code=0,
        log=("route wand", "warning: axes: cam2 sees 3 of the 4 axes markers"),
        kept="the other cameras fix the lab frame; the output says which camera missed which",
    ),
    Case(
        "contradicting-seeds",
        "calibration",
        "clicked two target seeds and gave each the other's coordinates",
        contradicting_seeds,
        ("calibrate", "S"),
        ("camera cam2", "seeds contradict each other", "rms", "seed row"),
    ),
    Case(
        "three-seeds",
        "calibration",
        "clicked only three target seeds in one camera",
        three_seeds,
        ("calibrate", "S"),
        ("camera cam2", "3 seeds", "at least 4", "7 numbers"),
        kept="nothing is calibrated; `kisscal validate` says the same",
    ),
    Case(
        "route-without-inputs",
        "calibration",
        "forced the target route on a session calibrated with rods",
        nothing,
        ("calibrate", "S", "--route", "target"),
        ("--route target", "no inputs for it", "[calibration] target"),
    ),
    Case(
        "cameras-toml-missing-camera",
        "calibration",
        "gave a cameras.toml without one of the session's cameras",
        imported_cameras(lambda doc: doc.pop("cam3")),
        ("calibrate", "S"),
        ("cameras.toml", "no camera named 'cam3'"),
    ),
    Case(
        "cameras-toml-missing-key",
        "calibration",
        "gave a cameras.toml camera without its rotation",
        imported_cameras(lambda doc: doc["cam2"].pop("rotation")),
        ("calibrate", "S"),
        ("[cam2] is missing rotation",),
    ),
    Case(
        "dltdv-ten-rows",
        "calibration",
        "gave DLT coefficients with 10 rows instead of 11",
        dltdv_rows(10),
        ("calibrate", "S"),
        ("coefs.csv", "expected 11 rows", "got 10"),
    ),
    Case(
        "c3d-no-points",
        "reconstruction",
        "gave a C3D trial whose every sample is invalid",
        empty_c3d,
        ("reconstruct", "S", "old"),
        ("empty.c3d", "no valid 3D point"),
    ),
    Case(
        "numbered-frames-missed",
        "reconstruction",
        "named a trial's frames cam1.10000, ... and gave the pattern numbered/{camera}.png",
        numbered_frames,
        ("reconstruct", "S", "ptv"),
        ("numbered/cam1.png", "no trial 'ptv' images", "misses every file", "cam1.10000"),
    ),
    Case(
        "video-shorter",
        "reconstruction",
        "gave one camera a video shorter than the others'",
        short_video,
        ("reconstruct", "S", "vid"),
        ("different numbers of frames", "cam2: 8"),
    ),
    Case(
        "unknown-marker-set",
        "tracking",
        "misspelt the marker set's name",
        toml_edit(lambda d: d.__setitem__("markers", {"set": "plug-in-gait-lowr"})),
        ("track", "S", "walk01"),
        ("markers.set", "'plug-in-gait-lowr'", "did you mean 'plug-in-gait-lower'"),
    ),
    Case(
        "marker-not-in-set",
        "tracking",
        "named a marker the chosen set does not have",
        toml_edit(
            lambda d: d.__setitem__(
                "markers", {"set": "plug-in-gait-lower", "names": ["LASI", "RASII"]}
            )
        ),
        ("track", "S", "walk01"),
        ("markers.names", "unknown marker 'RASII'", "did you mean 'RASI'"),
    ),
    Case(
        "static-not-a-trial",
        "tracking",
        "named a static trial that is not a [[trials]] entry",
        toml_edit(lambda d: d["markers"].__setitem__("static", "statc")),
        ("track", "S", "walk01"),
        ("markers.static = 'statc'", "not a [[trials]] name"),
    ),
    Case(
        "static-subject-moves",
        "tracking",
        "gave a walking trial as the static trial",
        toml_edit(lambda d: d["markers"].__setitem__("static", "walk01")),
        ("track", "S", "stick"),
        ("static trial 'walk01'", "the subject moves"),
    ),
    Case(
        "track-before-reconstruct",
        "tracking",
        "tracked a trial that was never reconstructed",
        lambda root: shutil.rmtree(root / "out" / "trials" / "walk01"),
        ("track", "S", "walk01"),
        ("points3d.csv", "run `kisscal reconstruct"),
    ),
    Case(
        "unknown-trial",
        "session",
        "misspelt a trial name",
        nothing,
        ("track", "S", "walk1"),
        ("no trial named 'walk1'", "did you mean 'walk01'"),
    ),
    Case(
        "unknown-camera",
        "session",
        "asked for a camera that is not in session.toml",
        nothing,
        ("linearise", "S", "--camera", "cam9"),
        ("no camera 'cam9'",),
    ),
    Case(
        "check-without-limits",
        "check",
        "ran kisscal check without a limit",
        nothing,
        ("check", "S"),
        ("give at least one of",),
    ),
    Case(
        "report-unrun",
        "report",
        "asked for the report of a session never run",
        lambda root: shutil.rmtree(root / "out"),
        ("report", "S"),
        ("nothing to report yet",),
        kept="nothing is written",
    ),
    Case(
        "session-toml-given",
        "session",
        "named session.toml instead of its folder",
        nothing,
        ("validate", "S/session.toml"),
        (),
        exit_code=0,
        log=("every input is present",),
        kept="every output",
    ),
    Case(
        "unfilled-template",
        "session",
        "left every rod of the init template unfilled",
        toml_edit(unfilled_rods),
        ("validate", "S"),
        ("still to fill in", "rods.rod[0].points_mm (R1)", "rods.rod[3].points_mm (R4)"),
    ),
    Case(
        "camera-folders-renamed",
        "session",
        "named the camera folders left, view2, ... instead of the camera ids",
        renamed_camera_folders,
        ("run", "S"),
        ("grid holds folders left, view2, view3, view4", "none named after a camera id"),
    ),
    Case(
        "late-small-frame",
        "session",
        "put a 320 x 240 frame at position 15 of 20",
        late_small_frame,
        ("validate", "S"),
        ("1 problem found",),
        log=("cam2", "000015.png is 320 x 240", "752 x 291"),
    ),
    Case(
        "jpeg-in-png",
        "session",
        "saved JPEG data under the .png names of a camera's frames",
        jpeg_in_png,
        ("validate", "S"),
        (),
        exit_code=0,
        log=(
            "warning",
            "cam2",
            "20 of 20",
            "JPEG data",
            "lossy compression moves marker centroids",
        ),
        kept="every output",
    ),
    Case(
        "absolute-images-pattern",
        "reconstruction",
        "gave an absolute images pattern",
        absolute_pattern,
        ("reconstruct", "S", "walk01"),
        (),
        exit_code=0,
        log=("reconstruct walk01",),
        kept="every output",
    ),
    Case(
        "c3d-other-rate",
        "session",
        "gave a C3D trial recorded at 100 Hz in a 50 Hz session",
        c3d_at_rate(100.0),
        ("validate", "S"),
        ("1 problem found",),
        log=("old.c3d", "recorded at 100 frames per second", "rate_hz = 50"),
    ),
    Case(
        "throw-wrong-rate",
        "tracking",
        "gave rate_hz = 30 for cameras at 50 Hz",
        toml_edit(lambda d: d["session"].update(rate_hz=30.0)),
        ("track", "S", "throw"),
        (),
        exit_code=0,
        log=("warning: throw", "3.53 m/s²", "rate_hz = 30 right?", "at 50 Hz"),
        kept="every output",
    ),
    Case(
        "detect-missing-image",
        "detection",
        "named an image that does not exist",
        nothing,
        ("detect", "S/nope.png"),
        ("nope.png", "not found"),
    ),
)


def markdown() -> str:
    """``docs/bad-inputs.md``: the catalogue as a table per stage."""
    lines = [
        "# Bad inputs",
        "",
        "What kisscal does when an input is wrong. Each row is a test",
        "(`tests/session/test_catalogue.py`, generated from `tests/session/catalogue.py`).",
        "Every error is one line, `kisscal <command>: error: ...`, the last line of the log",
        "(stderr; the lines before it say what was done), never a traceback; nothing already",
        "written is lost or half-overwritten. Rows with exit 0 list words of the log instead.",
        "",
        "| what the user did | command | kisscal says (words of the message) | exit | what is kept"
        " |",
        "|---|---|---|---|---|",
    ]
    for case in CASES:
        command = "kisscal " + " ".join(
            "SESSION" if a == "S" else a.replace("S/", "SESSION/") for a in case.args
        )
        says = " ... ".join(case.says or case.log).replace("|", "\\|")
        lines.append(f"| {case.did} | `{command}` | {says} | {case.exit_code} | {case.kept} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(markdown(), end="")
