"""The session hands reconstruction the subject's rigid triangles only when it has them."""

from types import SimpleNamespace

import numpy as np

from kisscal.io.config import MarkersConfig
from kisscal.session.reconstruct import session_body

NAMES = ("RASI", "LASI", "SACR")
TEMPLATE_MM = np.array([[0.0, -120.0, 0.0], [0.0, 120.0, 0.0], [-160.0, 0.0, 10.0]])
SEGMENTS = (("RASI", "LASI"), ("LASI", "SACR"), ("RASI", "SACR"))


def test_a_template_given_by_hand_becomes_the_pelvis_triangle() -> None:
    body = session_body(SimpleNamespace(markers=MarkersConfig(NAMES, TEMPLATE_MM, SEGMENTS)))
    assert body is not None and len(body) == 3  # one triangle seen from each corner
    between = np.linalg.norm(TEMPLATE_MM[:, None] - TEMPLATE_MM[None], axis=2)
    sides = sorted(np.r_[body.d_ij, body.d_ik, body.d_jk])
    expected = sorted(3 * [between[0, 1], between[1, 2], between[0, 2]])
    np.testing.assert_allclose(sides, expected)


def test_no_template_or_no_segments_means_no_body() -> None:
    for markers in (
        None,
        MarkersConfig(NAMES, None, SEGMENTS),  # a shipped set's template is only scaled
        MarkersConfig(NAMES, TEMPLATE_MM, ()),
    ):
        assert session_body(SimpleNamespace(markers=markers)) is None
