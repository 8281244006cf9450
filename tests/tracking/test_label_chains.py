"""Doubts that travel: along a chain of shifted names, and through a doubted name to a
front/back pair turned round (issue 26's test1.c3d and Vicon_analysis.c3d in small)."""

from dataclasses import replace

import numpy as np

from kisscal.markersets import marker_set
from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling.anatomy import Anatomy
from kisscal.tracking.labelling.sides import _turned, judge_sides
from tests.tracking.test_anatomy import _labelling

FULL = marker_set("plug-in-gait-full")
#: test1.c3d's chain: each of these markers holds the name before it (the sternum RBAK's).
CHAIN = ("STRN", "RELB", "RFRM", "RWRA", "RFIN", "RTHI", "RKNE", "RTIB", "RANK", "RHEE", "RTOE")


def _walk() -> np.ndarray:
    """The full set's template walking along x at 1.2 m/s (50 Hz), bobbing 20 mm."""
    fields = np.arange(100)
    shift = np.c_[24.0 * fields, np.zeros(100), 20.0 * np.sin(fields / 8.0)]
    return FULL.template_mm[:, None, :] + shift[None]


def _judge(pos: np.ndarray, labels: tuple[str, ...]):
    anatomy = Anatomy.of_set(FULL)
    t = FULL.template_mm
    return judge_sides(_labelling(pos, labels), anatomy, t, 50.0, TrackingParams(), t)


def test_a_chain_of_names_shifted_along_arm_and_leg_is_doubted_to_its_ends():
    """Every name held, each marker of the chain named as the next one up (the toe's
    name on a foreign marker ahead of the toe, the sternum's name on the elbow, RBAK's
    on the sternum): no name is free to compare with. Every name the judged labelling
    puts on another marker of the set is flagged (the foreign marker's name is, as in
    the acceptance table, an extra); the true names are not (but the wrist bars'
    twins)."""
    pos, names = _walk(), FULL.names
    keep = [i for i, n in enumerate(names) if n not in CHAIN and n != "RBAK"]
    rows = keep + [names.index(n) for n in CHAIN]
    labels = tuple(names[i] for i in keep) + ("RBAK",) + CHAIN[:-1] + ("RTOE",)
    truth = tuple(names[i] for i in rows) + ("foreign",)
    foreign = pos[names.index("RTOE")] + [60.0, 0.0, 0.0]
    judged = _judge(np.concatenate([pos[rows], foreign[None]]), labels)
    wrong = {
        got for got, true in zip(judged.labels, truth, strict=True) if true not in (got, "foreign")
    }
    assert {"RTIB", "RANK"} <= wrong  # the leg's end of the chain
    assert wrong <= set(judged.flagged)
    held = [i for i, n in enumerate(names) if n != "RBAK"]
    right = _judge(pos[held], tuple(names[i] for i in held))
    assert set(right.flagged) == {"LWRA", "LWRB", "RWRA", "RWRB"}


def test_a_doubted_name_on_the_true_back_marker_turns_a_trunk_name_round():
    """Without arms and head: the trunk's back name C7 on the clavicle marker, CLAV free,
    the true C7 marker behind it named LBHD. Only when LBHD is doubted does its marker
    count as the evidence an unnamed one would be (a name alone, its head absent); named
    right, nothing is turned."""
    pos, names = _walk(), FULL.names
    parts = ("SHO", "UPA", "ELB", "FRM", "WRA", "WRB", "FIN", "FHD", "BHD")
    keep = [n for n in names if n[1:] not in parts and n != "RBAK"]
    anatomy, t, params = Anatomy.of_set(FULL), FULL.template_mm, TrackingParams()

    def turned(mapping: dict[str, str], doubtful: set[str]) -> set[str]:
        """``mapping``: a marker's name when not its own ("": unnamed, None: absent)."""
        seen = [n for n in keep if mapping.get(n, n) is not None]
        moved = np.full_like(pos, np.nan)
        for n in seen:
            if mapping.get(n, n):
                moved[names.index(mapping.get(n, n))] = pos[names.index(n)]
        labels = tuple(mapping.get(n, n) for n in seen)
        labelling = replace(
            _labelling(pos[[names.index(n) for n in seen]], labels),
            unlabelled=tuple(i for i, n in enumerate(labels) if not n),
        )
        return _turned(labelling, moved, anatomy, t, 50.0, params, doubtful)

    shifted = {"CLAV": "C7", "C7": "LBHD"}
    assert turned(shifted, set()) == set()
    assert turned(shifted, {"LBHD"}) == {"C7"}
    # The clavicle's marker unnamed, or named by a doubted name, ahead of the true C7.
    assert turned({"CLAV": ""}, {"LBHD"}) == set()
    assert turned({"CLAV": "LFHD"}, {"LFHD"}) == set()
    # A doubted toe among its foot's names, ahead of the ankle, the heel absent: it is
    # still the foot's toe, no stand-in for a heel turned round.
    assert turned({"LHEE": None}, {"LTOE"}) == set()
