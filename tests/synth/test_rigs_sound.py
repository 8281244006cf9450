"""Every preset's rig is sound, whatever detection configures for itself.

With detection parameters derived by hand from the rig's truth (:mod:`tests.synth.
truth_params`) the pipeline must find the 300 grid dots and the 24 rod markers in every
camera and reconstruct a short walk: then a failure of self-configured detection on these
rigs is detection's, not the rig's.
"""

from __future__ import annotations

import pytest

from tests.synth.rig_check import RigFigures, check_rig

#: Largest walk 3D RMSE (mm) and stick length error (mm) per preset with these parameters:
#: the webcams' heavy noise and small markers give several times the others' error.
LIMITS = {"kiss": (0.6, 0.3), "modern": (0.4, 0.1), "lowcost": (1.5, 0.45)}


def assert_sound(fig: RigFigures) -> None:
    cams = len(fig.plan.rig)
    assert fig.grid_dots == [300] * cams, fig.grid_dots
    assert fig.rod_markers == [24] * cams, fig.rod_markers
    assert max(fig.grid_rms_px) < 0.1 and max(fig.dlt_rms_px) < 0.2
    assert fig.walk_recall_isolated >= 0.99  # markers whole and alone in >= 3 cameras
    assert fig.walk_recall >= 0.9 and fig.walk_ghosts == 0
    rmse_mm, stick_mm = LIMITS[fig.preset]
    assert fig.walk_rmse_mm < rmse_mm and fig.stick_mae_mm < stick_mm
    assert fig.walk_reproj_px < 0.1


@pytest.mark.parametrize(("preset", "cameras"), [("kiss", None), ("modern", 4), ("lowcost", None)])
def test_rig_is_sound_with_truth_derived_detection(preset: str, cameras: int | None) -> None:
    assert_sound(check_rig(preset, 1, walk_fields=10, stick_fields=10, n_cameras=cameras))


@pytest.mark.slow
@pytest.mark.parametrize(
    ("preset", "seed", "cameras"),
    [
        ("modern", 4, 8),  # 12-bit images
        ("modern", 2, 8),  # 10-bit images
        ("modern", 7, 4),  # 2048 x 2048 (four of them: the others test eight cameras)
        ("modern", 3, 12),
        ("lowcost", 4, None),
        ("lowcost", 7, None),
        ("kiss", 3, None),
    ],
)
def test_more_rigs_are_sound(preset: str, seed: int, cameras: int | None) -> None:
    assert_sound(check_rig(preset, seed, walk_fields=12, stick_fields=12, n_cameras=cameras))
