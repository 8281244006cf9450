"""Errors a caller can act on: bad input, missing data and a failed fit told apart, and
point arrays of the wrong shape refused instead of silently reshaped."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kisscal._shared import as_points
from kisscal.camera import Camera
from kisscal.dlt.linear import check_control_points
from kisscal.dlt.model import dlt_from_krt, project_rows
from kisscal.dlt.params import DltParams
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.errors import EstimationFailed, InputError, KisscalError, MissingDataError
from kisscal.io.files import read_table
from kisscal.recon.assign import check_table
from kisscal.recon.params import ReconParams
from kisscal.rig import Rig


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
