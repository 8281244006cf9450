"""Writing a synthetic known-target session: photographs, target.csv, seeds and truth.

The session calibrates with ``[calibration] target`` (:mod:`kisscal.synth.target` makes
the scene). Like :func:`kisscal.session.synth_session.write_synthetic_session` it is assembled in
a temporary sibling folder and moved into place at the end.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import tomli_w

from kisscal.io.files import staged_folder, write_json, write_table
from kisscal.synth.cameras import truth_dict
from kisscal.synth.target import (
    TargetKind,
    render_target,
    seed_points,
    target_points,
    target_rig,
    truth_table,
)


def write_target_session(
    out: Path,
    kind: TargetKind,
    seed: int = 1,
    n_cameras: int = 3,
    force: bool = False,
) -> Path:
    """A session calibrated from photographs of a ``planar`` or ``stepped`` dot plate.

    Writes ``target.csv``, ``calibration/<camera>/*.tif`` (two photographs per
    camera), ``calibration/<camera>_seeds.csv`` (six clicked points) and ``truth/``
    (``cameras.json``, ``target/<camera>.csv``).
    """
    out = Path(out)
    with staged_folder(out, force) as root:
        xyz, surfaces = target_points(kind)
        rig = target_rig(seed, n_cameras)
        config = {
            "session": {"name": f"target-{kind}-seed{seed}", "rate_hz": 50.0},
            "cameras": [{"id": c.id, "size": list(c.size_px)} for c in rig],
            "calibration": {
                "target": "target.csv",
                "images": "calibration/{camera}/*.tif",
                "seeds": "calibration/{camera}_seeds.csv",
            },
        }
        (root / "session.toml").write_text(tomli_w.dumps(config))
        write_table(root / "target.csv", {"x_mm": xyz[:, 0], "y_mm": xyz[:, 1], "z_mm": xyz[:, 2]})
        write_json(root / "truth" / "cameras.json", {"cameras": [truth_dict(c) for c in rig]})
        for ci, cam in enumerate(rig):
            folder = root / "calibration" / cam.id
            folder.mkdir(parents=True)
            for k in range(2):
                image = render_target(cam, xyz, surfaces, np.random.default_rng([seed, ci, k]))
                cv2.imwrite(str(folder / f"{k:04d}.tif"), image)
            uv, picked = seed_points(cam, xyz, np.random.default_rng([seed, ci, 99]))
            write_table(
                root / "calibration" / f"{cam.id}_seeds.csv",
                {
                    "u_px": uv[:, 0],
                    "v_px": uv[:, 1],
                    "x_mm": picked[:, 0],
                    "y_mm": picked[:, 1],
                    "z_mm": picked[:, 2],
                },
            )
            write_table(root / "truth" / "target" / f"{cam.id}.csv", truth_table(cam, xyz))
    return out
