"""Doubted names given again (kisscal.tracking.labelling.regive): a thigh marker named
finger with the arms absent takes the thigh's free name (issue 26's Vicon_analysis.c3d
without arms in small); a name given wrongly stays flagged."""

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling.anatomy import Anatomy
from kisscal.tracking.labelling.regive import regive_doubted
from kisscal.tracking.labelling.sides import judge_sides
from kisscal.tracking.labelling.state import segment_mask
from tests.tracking.test_anatomy import _labelling
from tests.tracking.test_label_chains import CHAIN, FULL, _walk

ARMS = ("SHO", "UPA", "ELB", "FRM", "WRA", "WRB", "FIN")


def _judge(labelling):
    t = FULL.template_mm
    return judge_sides(labelling, Anatomy.of_set(FULL), t, 50.0, TrackingParams(), t)


def _regiven(pos: np.ndarray, labels: tuple[str, ...]):
    judged = _judge(_labelling(pos, labels))
    segments = segment_mask(FULL.names, FULL.segments)
    return judged, regive_doubted(judged, Anatomy.of_set(FULL), FULL.template_mm, _judge, segments)


def test_thigh_markers_named_fingers_take_the_free_thigh_names():
    """Arms absent, each thigh marker named its side's finger, LTHI and RTHI free: the
    judge doubts the fingers' names; given again, the thighs hold their own names and
    nothing is flagged."""
    pos, names = _walk(), FULL.names
    keep = [i for i, n in enumerate(names) if n[1:] not in ARMS]
    truth = tuple(names[i] for i in keep)
    labels = tuple({"LTHI": "LFIN", "RTHI": "RFIN"}.get(n, n) for n in truth)
    judged, regiven = _regiven(pos[keep], labels)
    assert {"LFIN", "RFIN"} <= set(judged.flagged)  # the judge doubts them (before)
    assert regiven.labels == truth
    assert regiven.flagged == () and set(regiven.missing) == {n for n in names if n[1:] in ARMS}


def test_names_given_again_are_never_wrong_and_certain():
    """test1.c3d's chain (every name held, each marker of the chain named as the next
    one up, the toe's name on a foreign marker): whatever is given again, every name on
    another marker of the set stays flagged."""
    pos, names = _walk(), FULL.names
    keep = [i for i, n in enumerate(names) if n not in CHAIN and n != "RBAK"]
    rows = keep + [names.index(n) for n in CHAIN]
    labels = tuple(names[i] for i in keep) + ("RBAK",) + CHAIN[:-1] + ("RTOE",)
    truth = tuple(names[i] for i in rows) + ("foreign",)
    foreign = pos[names.index("RTOE")] + [60.0, 0.0, 0.0]
    _, regiven = _regiven(np.concatenate([pos[rows], foreign[None]]), labels)
    wrong = {
        got for got, true in zip(regiven.labels, truth, strict=True) if true not in (got, "foreign")
    }
    assert wrong and wrong <= set(regiven.flagged)


def test_a_labelling_with_nothing_doubted_is_left_as_it_is():
    pos, names = _walk(), FULL.names
    held = [i for i, n in enumerate(names) if n[1:] not in ARMS]
    judged, regiven = _regiven(pos[held], tuple(names[i] for i in held))
    assert judged.flagged == () and regiven is judged


def _swinging_legs() -> np.ndarray:
    """:func:`_walk` with each leg swinging rigidly about its hip (30 degrees, in
    opposition): a leg's markers keep their distances only to one another."""
    pos, names = _walk(), FULL.names
    angle = 0.5 * np.sin(np.arange(pos.shape[1]) / 8.0)
    for side, sign in (("L", 1.0), ("R", -1.0)):
        rows = [i for i, n in enumerate(names) if n[0] == side and n[1:] in LEG]
        hip = pos[names.index(f"{side}ASI")] - [0.0, 0.0, 50.0]  # (F, 3)
        c, s = np.cos(sign * angle), np.sin(sign * angle)
        rel = pos[rows] - hip
        pos[rows] = hip + np.stack(
            [c * rel[..., 0] + s * rel[..., 2], rel[..., 1], -s * rel[..., 0] + c * rel[..., 2]], -1
        )
    return pos


LEG = ("THI", "KNE", "TIB", "ANK", "HEE", "TOE")


def test_a_thigh_marker_placed_high_takes_the_thigh_name_its_segment_vouches_for():
    """Arms absent, the right thigh marker placed twice as far above the knee as the
    template's (at wrist height, analogfpscale03.c3d) and named RWRA, RTHI free: it fits
    the wrist's place better than the thigh's, but it keeps its distance to the knee
    marker, RTHI's segment partner, while the leg swings; given again it is RTHI."""
    pos, names = _swinging_legs(), FULL.names
    knee, thigh = names.index("RKNE"), names.index("RTHI")
    pos[thigh] = pos[knee] + 2.0 * (pos[thigh] - pos[knee])
    keep = [i for i, n in enumerate(names) if n[1:] not in ARMS]
    truth = tuple(names[i] for i in keep)
    judged, regiven = _regiven(pos[keep], tuple({"RTHI": "RWRA"}.get(n, n) for n in truth))
    assert "RWRA" in judged.flagged  # the judge doubts it (before)
    assert regiven.labels == truth
