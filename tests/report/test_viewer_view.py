"""The 3D viewer's first view holds every camera and every sample of the trial."""

from __future__ import annotations

import numpy as np

from kisscal.report.viewer import VIEWER_JS, default_view, viewer_data


def test_default_view_reaches_every_camera_and_sample() -> None:
    rng = np.random.default_rng(2)
    walk = np.round(rng.uniform([-1500, -300, 0], [1500, 300, 1000], (3, 50, 3)))
    walk[0, 10] = np.nan
    xyz = [[None if not np.isfinite(v) else int(v) for v in m.ravel()] for m in walk]
    cameras = {"cam1": [-2562, -4070, 1628], "cam2": [-4, 4391, 1741], "bad": None}
    data = viewer_data({"walk": {"name": "walk", "xyz": xyz}}, cameras)
    view = data["trials"][0]["view"]
    centre, radius = np.array(view["centre"]), view["radius"]
    samples = walk.reshape(-1, 3)[np.isfinite(walk.reshape(-1, 3)).all(axis=1)]
    assert np.allclose(centre, (samples.min(axis=0) + samples.max(axis=0)) / 2, atol=0.1)
    for point in (*samples, *(np.array(c, float) for c in cameras.values() if c)):
        assert np.linalg.norm(point - centre) <= radius
    assert [c["id"] for c in data["cameras"]] == ["cam1", "cam2"]
    # the script starts from this sphere, and draws any point inside it on screen: at most
    # 6/5 nearer in perspective (eye 6 radii away), 1.2 / 2.6 of the canvas from its middle
    assert "centre = trial.view.centre; radius = trial.view.radius" in VIEWER_JS
    assert "dist = 6 * radius" in VIEWER_JS and "/ (2.6 * radius)" in VIEWER_JS


def test_a_trial_without_samples_is_shown_around_the_cameras() -> None:
    view = default_view([[None, None, None]], np.array([[5000.0, 0.0, 1000.0]]))
    assert view["radius"] >= np.linalg.norm(np.array([5000.0, 0, 1000]) - view["centre"])
