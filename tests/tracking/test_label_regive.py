"""Doubted names given again (kisscal.tracking.labelling.regive): a thigh marker named
finger with the arms absent takes the thigh's free name (issue 26's Vicon_analysis.c3d
without arms in small); a name given wrongly stays flagged."""

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling.anatomy import Anatomy
from kisscal.tracking.labelling.regive import regive_doubted
from kisscal.tracking.labelling.sides import judge_sides
from tests.tracking.test_anatomy import _labelling
from tests.tracking.test_label_chains import CHAIN, FULL, _walk

ARMS = ("SHO", "UPA", "ELB", "FRM", "WRA", "WRB", "FIN")


def _judge(labelling):
    t = FULL.template_mm
    return judge_sides(labelling, Anatomy.of_set(FULL), t, 50.0, TrackingParams(), t)


def _regiven(pos: np.ndarray, labels: tuple[str, ...]):
    judged = _judge(_labelling(pos, labels))
    return judged, regive_doubted(judged, Anatomy.of_set(FULL), FULL.template_mm, _judge)


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
