"""Loading the marker sets kisscal ships (package data files, TOML)."""

from __future__ import annotations

import functools
import sys
from collections.abc import Sequence
from importlib import resources
from types import MappingProxyType

import numpy as np

from kisscal.errors import InputError
from kisscal.markersets.model import MarkerSet, unknown_message

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def available_marker_sets() -> tuple[str, ...]:
    """Names of the marker sets kisscal ships, sorted."""
    files = resources.files("kisscal.markersets").joinpath("data").iterdir()
    return tuple(sorted(f.name[: -len(".toml")] for f in files if f.name.endswith(".toml")))


def marker_set(name: str, names: Sequence[str] | None = None) -> MarkerSet:
    """A shipped marker set by name, optionally restricted to (or reordered as) ``names``.

    Parameters
    ----------
    name : str
        ``"plug-in-gait-lower"``, ``"plug-in-gait-full"`` or ``"kiss"`` (see
        :func:`available_marker_sets`).
    names : sequence of str, optional
        The markers used, in the session's order; default the set's own list. Any marker
        the set defines may be picked, e.g. ``SACR`` instead of ``LPSI`` and ``RPSI`` in
        Plug-in Gait, or the 13 KISS markers without ``RASI`` and ``LASI``; names of the
        set's ``aliases`` are accepted and mapped to the set's names.

    Returns
    -------
    MarkerSet

    Raises
    ------
    KisscalError
        Unknown set or marker (one line, with a did-you-mean), or a marker given twice.

    References
    ----------
    Davis et al. 1991 (Plug-in Gait lower body); Küçük 2005 (the KISS set); Winter 2009
    and Bell et al. 1990 (the templates' geometry, see ``tests/markersets/derive_markersets.py``).

    Examples
    --------
    >>> pig = marker_set("plug-in-gait-lower")
    >>> len(pig), pig.foot("left")["heel"]
    (16, 'LHEE')
    >>> marker_set("plug-in-gait-lower", names=["LASI", "RASI", "SACR"]).names
    ('LASI', 'RASI', 'SACR')
    >>> round(float(pig.scaled(1900.0).position("LASI")[2]))
    1081
    """
    return _load(name).select(tuple(_raw(name)["names"] if names is None else names))


@functools.cache
def _raw(name: str) -> dict:
    known = available_marker_sets()
    if name not in known:
        raise InputError(
            f"{unknown_message(name, known, 'marker set')}; kisscal ships: {', '.join(known)}"
        )
    text = resources.files("kisscal.markersets").joinpath("data", f"{name}.toml").read_text("utf-8")
    return tomllib.loads(text)


@functools.cache
def _load(name: str) -> MarkerSet:
    raw = _raw(name)
    markers = raw["markers"]
    all_names = tuple(markers)
    roles = {
        "pelvis": tuple(raw["roles"]["pelvis"]),
        **{side: MappingProxyType(dict(raw["roles"][side])) for side in ("left", "right")},
    }
    height = float(raw["reference_height_mm"])
    return MarkerSet(
        name=raw["name"],
        names=all_names,
        template_mm=np.array([markers[n]["xyz_mm"] for n in all_names], dtype=float),
        sd_mm=np.array([markers[n]["sd_mm"] for n in all_names], dtype=float),
        placement_sd_mm=np.array([markers[n]["placement_sd_mm"] for n in all_names], dtype=float),
        proportion_cv=float(raw["proportion_cv"]),
        segments=tuple(tuple(p) for p in raw["segments"]),
        hinge_segments=tuple(tuple(p) for p in raw["hinge_segments"]),
        mirror=tuple(tuple(p) for p in raw["mirror"]),
        midline=tuple(raw["midline"]),
        roles=MappingProxyType(roles),
        aliases=MappingProxyType(dict(raw["aliases"])),
        height_mm=height,
        reference_height_mm=height,
        frame=raw["frame"],
        source=raw["source"],
        description=raw["description"],
    )
