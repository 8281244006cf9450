"""Automatic labelling of tracks with a marker set (beyond the seeds, which left it to the
operator).

Input: blended pieces and the ``[markers]`` set (names, a template of positions in a
standing pose in any coordinate frame, optional rigid segments). Nothing depends on where
the subject stands or faces. The phases run on one :class:`~.state.LabelState`:

1. :mod:`~.window`, average pose: in a window where most long pieces are seen together,
   the median distance between every pair of pieces is taken (it averages out the swing
   of the legs) and turned into points by classical MDS; these are matched to the
   template by rigid fits (24 starts, Hungarian + Kabsch), refined by exchanging names
   to fit the distances that stay constant (markers on one segment), and of a
   correspondence and its left/right mirror image (equal in distances) the one that
   fits the real fields with a proper rotation is kept; of a long window and shorter
   ones, a match facing forward along the walk beats one turned round (:mod:`~.facing`),
   and a shorter window's more names must agree with the kept ones. With a shipped (upright) set,
   when the window's average pose stood on the template (:mod:`~.upright`) finds
   pieces for less than two thirds of the names (a full-body set on a lower-body file,
   markers of another set), only those pieces and names enter the search, so absent
   names are never forced on foreign pieces.
2. :mod:`~.spread`, spreading: other pieces take the free name (not held in their
   fields) whose rigid partners keep the template distance from them; repeated as names
   spread through time.
3. :mod:`~.spread`, rematching: windows where unnamed long pieces remain are matched
   again.
4. :mod:`~.groups`: groups of unnamed pieces that entered the view together (a whole
   foot) are named jointly.
5. :mod:`~.learned`: long pieces still unnamed (no named partner in their fields: a
   toe seen again after its heel has gone) take the free name whose distances to the
   names around them they keep as the trial showed them.
   :mod:`~.unseen`: a piece of a marker whose name the trial never showed (a thigh
   seen by two cameras for a few fields, its knee never) takes that name when it keeps
   its template distances to the names held around it clearly best of all names.
   Then (:mod:`~.facing`) a foot's heel and toe pieces named the wrong way round
   are renamed: along the walk the toe is ahead.
6. :mod:`~.result`, joining: pieces sharing a name are joined. Short pieces that fit no
   name are ghosts and are dropped (Shafiq et al. 2001's clean-up); long ones are kept,
   named ``M<k>`` and reported. When too few names are matched (a stick, a thrown ball),
   all tracks are named M1, M2, ... .

With a shipped marker set and no template, :mod:`~.vertical` first finds which lab
axis is up (a body is tallest along the vertical; stood on its head it does not fit the
standing template), and :mod:`~.subject` the subject's stature and own template from
the trial; every labelling made with a set, or with names following the ``L``/``R``
convention, is then judged by the anatomy (:mod:`~.anatomy`,
:mod:`~.sides`): left and right settled by the walking direction and the pelvis, a
confidence per name, uncertain names flagged: names the checks cannot tell apart (a
wrist bar's two ends), names that another name of the set fits clearly better
against the set's own template, or a name left free fits better (by any margin when
none of the name's template neighbours is held), legs not level with each other, a
segment's front or back name held alone with an unnamed marker (or one whose name is
doubted) moving rigidly on its wrong side (:mod:`~.runnerup`), and a foot's names that a
near tie of the feet contest gives to other markers (:mod:`~.feet`). Doubt travels along
the names trajectories prefer: a name whose holder is doubted is as good as free (a chain
of names shifted along a limb holds every name).
A doubted trajectory then keeps its name or takes a free name of a group the trial
records that fits it better (:mod:`~.regive`: a finger's name on a thigh marker with
the arms absent gives way to the thigh's); the result is judged again and kept when
fewer names are doubted, a moved name certain only when it is its trajectory's best.

The rigid geometry (Kabsch fits, rigid correspondences, classical MDS, the swap search)
is in :mod:`kisscal.tracking.rigid`.
"""

from kisscal.tracking.labelling.label import label_tracks
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.labelling.subject import label_with_set

__all__ = ["Labelling", "label_tracks", "label_with_set"]
