"""The markers gait analysis needs (pelvis, heel and toe per side), found by their roles."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import InputError
from kisscal.gait.params import DEFAULT_PARAMS, GaitParams
from kisscal.gait.table import SIDES
from kisscal.markersets.model import MarkerSet


@dataclass(frozen=True, eq=False)
class GaitMarkers:
    """Trajectories (n_fields, 3) in lab mm, NaN in gaps, at ``rate_hz``.

    Attributes
    ----------
    pelvis : tuple of ndarray
        Every pelvis marker present (ASIS, PSIS, sacrum): the pelvis' velocity is the
        mean of theirs, so a marker missing in part of the trial does not jolt it.
    heel, toe : dict
        Side (``"left"`` / ``"right"``) -> trajectory.
    rate_hz : float
    names : dict
        What each role was taken from (for messages and figures).
    heel_from_ankle : tuple of str
        Sides whose heel is a stand-in placed behind the ankle marker
        (:func:`heel_from_ankle`), the foot having no heel marker.
    """

    pelvis: tuple[NDArray[np.float64], ...]
    heel: dict[str, NDArray[np.float64]]
    toe: dict[str, NDArray[np.float64]]
    rate_hz: float
    names: dict[str, str]
    heel_from_ankle: tuple[str, ...] = ()

    @property
    def n_fields(self) -> int:
        return self.pelvis[0].shape[0]

    @property
    def time_s(self) -> NDArray[np.float64]:
        return np.arange(self.n_fields) / self.rate_hz


def heel_from_ankle(
    ankle: ArrayLike, toe: ArrayLike, behind_mm: float = DEFAULT_PARAMS.ankle_heel_mm
) -> NDArray[np.float64]:
    """A heel stand-in (n, 3) for a foot without a heel marker: the point ``behind_mm``
    behind the ankle marker on the line from the toe marker through it.

    From foot strike to foot flat the foot turns about the heel, and the ankle marker,
    ahead of the heel and above it, keeps sinking meanwhile (some 10 mm): its lowest
    point comes 50-80 ms after the strike, where the foot lies flat. A point fixed to the
    foot behind the ankle (the line toe-ankle carried on backwards) rises by about as
    much as the ankle sinks while the toes come down, so it comes to rest when the heel
    lands, as a heel marker does. Only the ankle's and the toe's positions are used (no
    model of the foot); the foot's pitch along the line is the ankle's (foot off is
    unchanged).

    References
    ----------
    Perry 1992 (the heel rocker: the foot turns about the heel from initial contact to
    foot flat); Ghoussayni, Stevens, Durham & Ewins 2004 (heel contact where
    the heel comes to rest).

    Examples
    --------
    >>> ankle, toe = np.array([[0.0, 0.0, 80.0]]), np.array([[120.0, 0.0, 30.0]])
    >>> heel_from_ankle(ankle, toe, 39.0).round(1).tolist()
    [[-36.0, 0.0, 95.0]]
    """
    ankle = np.asarray(ankle, dtype=float)
    back = ankle - np.asarray(toe, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return ankle + behind_mm * back / np.linalg.norm(back, axis=-1, keepdims=True)


def gait_markers(
    markers: Mapping[str, ArrayLike],
    rate_hz: float,
    marker_set: MarkerSet,
    params: GaitParams = DEFAULT_PARAMS,
) -> GaitMarkers:
    """Pick the pelvis, heel and toe trajectories out of ``markers`` by the set's roles.

    Parameters
    ----------
    markers : mapping of str to (n_fields, 3) arrays
        Labelled trajectories (mm, NaN in gaps). Names may be the set's own or its
        ``aliases`` (e.g. walking5.c3d's ``LCAL`` for Plug-in Gait's ``LHEE``).
    rate_hz : float
    marker_set : MarkerSet
        Names the heel, toe, ankle and pelvis markers (:attr:`MarkerSet.roles`).
    params : GaitParams
        ``ankle_heel_mm``: where a foot has no heel marker (none in the trial, or one
        with no valid sample) but an ankle one, its heel is :func:`heel_from_ankle`.

    Raises
    ------
    InputError
        A toe marker, a heel marker and its ankle stand-in, or every pelvis marker, is
        missing (one line).
    """
    if not rate_hz > 0:
        raise InputError(f"gait: rate_hz must be > 0, got {rate_hz!r}")
    table = {}
    for name, xyz in markers.items():
        arr = np.asarray(xyz, dtype=float)
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise InputError(f"gait: marker {name!r} must be (n_fields, 3), got {arr.shape}")
        table[marker_set.aliases.get(name, name)] = arr
    lengths = {a.shape[0] for a in table.values()}
    if len(lengths) > 1:
        raise InputError(f"gait: markers have different numbers of fields {sorted(lengths)}")
    pelvis = tuple(table[n] for n in marker_set.pelvis if n in table)
    if not pelvis:
        raise InputError(
            f"gait: no pelvis marker among {', '.join(marker_set.pelvis)} (set {marker_set.name!r})"
        )
    used = {"pelvis": ",".join(n for n in marker_set.pelvis if n in table)}
    roles: dict[str, dict[str, NDArray]] = {"heel": {}, "toe": {}}
    stand_in = []
    for side in SIDES:
        foot = dict(marker_set.foot(side))
        heel, ankle = foot.get("heel"), foot.get("ankle")
        if not _seen(table, heel) and _seen(table, ankle) and _seen(table, foot.get("toe")):
            stand_in.append(side)
            foot["heel"] = ankle
        for role in ("heel", "toe"):
            name = foot.get(role)
            if name is None or name not in table:
                raise InputError(
                    f"gait: no {side} {role} marker ({name or 'none in set'} "
                    f"of {marker_set.name!r}) among the trial's markers"
                )
            roles[role][side] = table[name]
            used[f"{side}_{role}"] = name
        if side in stand_in:
            roles["heel"][side] = heel_from_ankle(
                table[foot["heel"]], roles["toe"][side], params.ankle_heel_mm
            )
    heel, toe = roles["heel"], roles["toe"]
    return GaitMarkers(pelvis, heel, toe, float(rate_hz), used, tuple(stand_in))


def _seen(table: Mapping[str, NDArray], name: str | None) -> bool:
    """Whether marker ``name`` is in ``table`` with at least one valid sample."""
    return name is not None and name in table and bool(np.isfinite(table[name]).all(1).any())
