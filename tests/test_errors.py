"""Errors a caller can act on: bad input, missing data and a failed fit told apart, and
point arrays of the wrong shape refused instead of silently reshaped."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from kisscal import session
from kisscal._shared import as_points
from kisscal.camera import Camera
from kisscal.detect.sequence import detect_sequence
from kisscal.dlt.calibrate import calibrate_camera
from kisscal.dlt.linear import check_control_points
from kisscal.dlt.model import dlt_from_krt, project_rows
from kisscal.dlt.params import DltParams
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.errors import (
    EstimationFailed,
    InputError,
    KisscalError,
    MissingDataError,
    with_context,
)
from kisscal.io.config import load_session
from kisscal.io.files import read_table
from kisscal.io.frames import image_header
from kisscal.io.linearisation import linearisation_from_dict
from kisscal.recon.assign import check_table
from kisscal.recon.params import ReconParams
from kisscal.rig import Rig
from tests.io.blob_csv import read_blobs


def _rig() -> Rig:
    K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
    left = Camera.from_dlt(dlt_from_krt(K, np.eye(3), [0, 0, 3000.0]), "left")
    right = Camera.from_dlt(dlt_from_krt(K, np.eye(3), [-500.0, 0, 3000]), "right")
    return Rig((left, right))


@pytest.mark.parametrize("cls", [InputError, MissingDataError, EstimationFailed])
def test_every_error_is_a_kisscal_error_the_cli_reports_on_one_line(cls: type) -> None:
    error = cls("what went wrong")
    assert isinstance(error, KisscalError) and isinstance(error, ValueError)
    assert error.exit_code == 2 and str(error) == "what went wrong"


def test_the_three_kinds_are_distinct_and_a_missing_file_is_a_file_not_found() -> None:
    kinds = (InputError, MissingDataError, EstimationFailed)
    for a in kinds:
        assert [issubclass(a, b) for b in kinds].count(True) == 1
    assert issubclass(MissingDataError, FileNotFoundError)
    assert not issubclass(InputError, FileNotFoundError)


def test_as_points_keeps_a_table_and_lifts_one_point() -> None:
    xyz = np.arange(12.0).reshape(4, 3)
    assert np.array_equal(as_points(xyz, 3), xyz)
    assert as_points([1.0, 2.0, 3.0], 3).tolist() == [[1.0, 2.0, 3.0]]
    assert as_points([[1, 2]], 2).dtype == np.float64
    assert as_points(np.zeros(0), 2).shape == (0, 2)


@pytest.mark.parametrize(
    ("shape", "dim"), [((2, 6), 3), ((6, 2), 3), ((4,), 3), ((3, 1, 3), 3), ((4, 3), 2)]
)
def test_as_points_refuses_what_would_have_been_reshaped(shape: tuple, dim: int) -> None:
    with pytest.raises(InputError, match=rf"shape \(n, {dim}\), got \({shape[0]},"):
        as_points(np.zeros(shape), dim)


def test_as_points_refuses_what_is_not_numbers() -> None:
    with pytest.raises(InputError, match="array of numbers"):
        as_points([["a", "b", "c"]], 3)


def test_rig_project_refuses_a_2_by_6_array_instead_of_making_4_points() -> None:
    rig = _rig()
    six = np.arange(12.0).reshape(2, 6) * 100
    with pytest.raises(InputError, match=r"xyz_mm must have shape \(n, 3\), got \(2, 6\)"):
        rig.project(six)
    assert rig.project(six.reshape(4, 3)).shape == (2, 4, 2)  # the points it meant


def test_triangulation_and_projection_entry_points_check_their_points() -> None:
    rig = _rig()
    with pytest.raises(InputError, match=r"uv must have shape \(n, 2\)"):
        triangulate_observations(rig.dlts, [0, 0], [0, 1], np.zeros((2, 4)))
    with pytest.raises(InputError, match=r"xyz_mm must have shape \(n, 3\)"):
        project_rows(rig.dlts, [0, 1], np.zeros((2, 6)))
    with pytest.raises(InputError, match=r"uv must have shape \(n, 2\), got \(3, 4\)"):
        check_table([0, 0, 0], [0, 1, 0], np.zeros((3, 4)), 2)


def test_target_and_object_entry_points_refuse_a_table_of_the_wrong_shape() -> None:
    """A (2, 6) table of lab points was reshaped into four points; now it is named."""
    from kisscal.bundle.frame import recognise_object
    from kisscal.target.dots import seed_offsets_px
    from kisscal.target.resect import resect

    six = np.arange(12.0).reshape(2, 6)
    with pytest.raises(InputError, match=r"xyz_mm must have shape \(n, 3\), got \(2, 6\)"):
        resect(six, np.zeros((4, 2)), (640, 480))
    with pytest.raises(InputError, match=r"object_mm must have shape \(n, 3\)"):
        recognise_object(np.zeros((4, 3)), six)
    with pytest.raises(InputError, match=r"points_px must have shape \(n, 2\), got \(1, 4\)"):
        seed_offsets_px(np.zeros((3, 2)), [[0.0, 0.0, 1.0, 1.0]])
    assert seed_offsets_px(np.zeros((3, 2)), [0.5, 0.0]).tolist() == [0.5]  # one point, flat


def test_a_missing_file_is_missing_data(tmp_path: Path) -> None:
    with pytest.raises(MissingDataError, match="file not found"):
        read_table(tmp_path / "nothing.csv")


def test_a_bad_setting_is_an_input_error() -> None:
    with pytest.raises(InputError, match="max_candidates"):
        ReconParams(max_candidates=0)


def test_coplanar_control_points_are_a_failed_estimation() -> None:
    rng = np.random.default_rng(3)
    xyz = np.column_stack([rng.uniform(-500, 500, (20, 2)), np.zeros(20)])
    uv = rng.uniform(0, 640, (20, 2))
    with pytest.raises(EstimationFailed, match="coplanar"):
        check_control_points(xyz, uv, DltParams())


PACKAGE = Path(__file__).resolve().parents[1] / "kisscal"
KINDS = ("KisscalError", "InputError", "MissingDataError", "EstimationFailed")

#: The sites that raise the base class, by (module, function), each with its reason.
BASE_CLASS_SITES = {
    ("cli/commands.py", "validate"): "the problems listed are of several kinds",
    ("session/run.py", "_run"): "trials fail for different reasons, each named in the message",
    ("session/run.py", "_stop_on_session_problems"): "validate's problems: several kinds",
    ("io/lock.py", "_acquire"): "the session is busy, neither wrong, missing nor failed",
    ("session/batch.py", "_dask"): "an optional package is not installed",
}


def _raises(tree: ast.AST, where: str = "") -> Iterator[tuple[str, ast.Raise]]:
    """Every ``raise`` of a module with the name of the function it stands in."""
    for node in ast.iter_child_nodes(tree):
        inner = node.name if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) else where
        if isinstance(node, ast.Raise):
            yield where, node
        yield from _raises(node, inner)


def _called(node: ast.Raise) -> str | None:
    """The class name a ``raise Name(...)`` calls, else None."""
    call = node.exc
    if isinstance(call, ast.Call) and isinstance(call.func, ast.Name):
        return call.func.id
    return None


def _modules() -> Iterator[tuple[str, ast.Module]]:
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path.relative_to(PACKAGE).as_posix(), ast.parse(path.read_text("utf-8"))


def test_the_base_class_is_raised_only_where_several_kinds_meet() -> None:
    found = {
        (module, function)
        for module, tree in _modules()
        for function, node in _raises(tree)
        if _called(node) == "KisscalError"
    }
    assert found - BASE_CLASS_SITES.keys() == set(), "raise InputError, MissingDataError or ..."
    assert BASE_CLASS_SITES.keys() - found == set(), "an allowed site is gone: drop it here"


def test_context_added_to_an_error_keeps_its_kind() -> None:
    """Inside ``except KisscalError as exc``, an error quoting ``exc`` must be made by
    :func:`with_context`, which keeps the kind, not by naming a class."""
    bad = []
    for module, tree in _modules():
        for handler in ast.walk(tree):
            if not (isinstance(handler, ast.ExceptHandler) and handler.name):
                continue
            caught = {n.id for n in ast.walk(handler.type) if isinstance(n, ast.Name)}
            if not caught & set(KINDS):
                continue
            for _, node in _raises(ast.Module(body=handler.body, type_ignores=[])):
                if _called(node) not in KINDS:
                    continue
                names = {n.id for n in ast.walk(node.exc) if isinstance(n, ast.Name)}
                if handler.name in names:
                    bad.append(f"{module}:{node.lineno}")
    assert bad == []


@pytest.mark.parametrize("cls", [InputError, MissingDataError, EstimationFailed])
def test_with_context_keeps_the_kind_and_the_message(cls: type) -> None:
    error = with_context(cls("what"), "camera c1: ", "; and why")
    assert type(error) is cls and str(error) == "camera c1: what; and why"


def test_a_wrapped_linearisation_error_is_still_an_input_error() -> None:
    doc = {"center_px": [1, 2], "scale_px": -1.0, "x": [0.0] * 15, "y": [0.0] * 15}
    with pytest.raises(InputError, match=r"^cam1\.json: linearisation scale_px must be positive"):
        linearisation_from_dict(doc, "cam1.json")


def _session(root: Path, rate_hz: object = 100) -> Path:
    """A two-camera session without calibration inputs: enough to be read."""
    root.mkdir()
    cameras = '[[cameras]]\nid = "{}"\nsize = [640, 480]\n\n'
    (root / "session.toml").write_text(
        f'[session]\nname = "s"\nrate_hz = {rate_hz!r}\n\n'.replace("'", '"')
        + cameras.format("cam1")
        + cameras.format("cam2")
        + '[[trials]]\nname = "walk01"\nimages = "trials/walk01/{camera}/*.png"\n'
    )
    return root


def test_reading_a_session_that_is_not_there_is_missing_data(tmp_path: Path) -> None:
    with pytest.raises(MissingDataError, match="session folder not found"):
        load_session(tmp_path / "nowhere")


def test_a_malformed_session_toml_value_is_an_input_error(tmp_path: Path) -> None:
    assert load_session(_session(tmp_path / "good")).rate_hz == 100.0
    with pytest.raises(InputError, match=r"session.rate_hz must be a number, got 'fast'"):
        load_session(_session(tmp_path / "bad", "fast"))


def test_reconstructing_before_calibrating_is_missing_data(tmp_path: Path) -> None:
    root = _session(tmp_path / "s")
    with pytest.raises(MissingDataError, match=r"dlt/cam1\.json: missing; run `kisscal calibr"):
        session.reconstruct(root, "walk01")


def test_a_dlt_from_4_points_is_a_failed_estimation() -> None:
    rng = np.random.default_rng(5)
    xyz = rng.uniform(-500, 500, (8, 3))
    uv = _rig().project(xyz)[0]
    assert calibrate_camera(xyz, uv, DltParams(), "left").L.shape == (11,)
    with pytest.raises(EstimationFailed, match="needs at least 6 control points, got 4"):
        calibrate_camera(xyz[:4], uv[:4], DltParams(), "left")


def test_files_not_there_and_files_not_readable_are_told_apart(tmp_path: Path) -> None:
    with pytest.raises(MissingDataError, match="not found"):
        read_blobs(tmp_path / "blobs.csv")
    with pytest.raises(MissingDataError, match="file not found"):
        image_header(tmp_path / "frame.png")
    (tmp_path / "frame.png").write_text("not an image")
    with pytest.raises(InputError, match="not a readable image"):
        image_header(tmp_path / "frame.png")


@pytest.mark.parametrize("workers", [1, 2])
def test_a_frame_that_fails_keeps_its_kind_through_the_detection_pool(workers: int) -> None:
    def load(i: int) -> np.ndarray:
        if i == 2:
            raise MissingDataError(f"frame {i}: not there")
        return np.zeros((8, 8), np.uint8)

    assert [len(b) for b in detect_sequence(load, count=2, workers=workers)] == [0, 0]
    with pytest.raises(MissingDataError, match="frame 2: not there"):
        detect_sequence(load, count=4, workers=workers, chunksize=1)
