"""The markers gait analysis needs (pelvis, heel and toe per side), found by their roles."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import InputError
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
    """

    pelvis: tuple[NDArray[np.float64], ...]
    heel: dict[str, NDArray[np.float64]]
    toe: dict[str, NDArray[np.float64]]
    rate_hz: float
    names: dict[str, str]

    @property
    def n_fields(self) -> int:
        return self.pelvis[0].shape[0]

    @property
    def time_s(self) -> NDArray[np.float64]:
        return np.arange(self.n_fields) / self.rate_hz


def gait_markers(
    markers: Mapping[str, ArrayLike], rate_hz: float, marker_set: MarkerSet
) -> GaitMarkers:
    """Pick the pelvis, heel and toe trajectories out of ``markers`` by the set's roles.

    Parameters
    ----------
    markers : mapping of str to (n_fields, 3) arrays
        Labelled trajectories (mm, NaN in gaps). Names may be the set's own or its
        ``aliases`` (e.g. walking5.c3d's ``LCAL`` for Plug-in Gait's ``LHEE``).
    rate_hz : float
    marker_set : MarkerSet
        Names the heel, toe and pelvis markers (:attr:`MarkerSet.roles`).

    Raises
    ------
    KisscalError
        A heel or toe marker, or every pelvis marker, is missing (one line).
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
    for side in SIDES:
        foot = marker_set.foot(side)
        for role in ("heel", "toe"):
            name = foot.get(role)
            if name is None or name not in table:
                raise InputError(
                    f"gait: no {side} {role} marker ({name or 'none in set'} "
                    f"of {marker_set.name!r}) among the trial's markers"
                )
            roles[role][side] = table[name]
            used[f"{side}_{role}"] = name
    return GaitMarkers(pelvis, roles["heel"], roles["toe"], float(rate_hz), used)
