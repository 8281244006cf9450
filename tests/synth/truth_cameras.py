"""The cameras of a synthetic session's ``truth/cameras.json`` read back (what
:func:`kisscal.synth.cameras.truth_dict` wrote): the package never reads its truth, the
tests do."""

from __future__ import annotations

import numpy as np

from kisscal.camera import Camera
from kisscal.synth.cameras import brown_lens


def camera_from_truth(d: dict) -> Camera:
    """The camera of one entry of ``truth/cameras.json`` (inverse of :func:`truth_dict`)."""
    lens = {k: float(v) for k, v in d["distortion"].items()}
    return Camera(
        np.asarray(d["K"], dtype=float),
        np.asarray(d["R"], dtype=float),
        np.asarray(d["t"], dtype=float),
        brown_lens(**lens),
        str(d["id"]),
        (int(d["size"][0]), int(d["size"][1])),
    )
