"""A marker set: names, rigid segments, mirror pairs, gait roles and a standing template."""

from __future__ import annotations

import copyreg
import difflib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

from kisscal.errors import InputError

Pair = tuple[str, str]


def _mapping_proxy(items: dict) -> MappingProxyType:
    return MappingProxyType(items)


def _pickle_mapping_proxy(proxy: MappingProxyType) -> tuple:
    # rebuilt by a module-level function: the type itself pickles by a name that
    # builtins does not have ("mappingproxy"), so it cannot be the callable here
    return _mapping_proxy, (dict(proxy),)


# A marker set travels to the process that draws the stage and gait figures (read-only
# views of its roles included; Python cannot pickle those by itself).
copyreg.pickle(MappingProxyType, _pickle_mapping_proxy)


@dataclass(frozen=True, eq=False)
class MarkerSet:
    """A marker set kisscal ships, or a selection of its markers.

    Attributes
    ----------
    name : str
        The set's name (``"plug-in-gait-lower"``, ...).
    names : tuple of str
        Marker names, in the order of the rows of ``template_mm`` and ``sd_mm``.
    template_mm : ndarray, shape (n, 3)
        Marker centres of a typical adult of ``height_mm`` standing upright, feet flat,
        in the frame ``frame`` (X forward, Y left, Z up, floor at Z = 0).
    sd_mm : ndarray, shape (n,)
        Plausible spread of each marker's position (per coordinate) across adults of that
        height: marker placement plus body proportions. Scales with height.
    placement_sd_mm : ndarray, shape (n,)
        The marker-placement part of ``sd_mm``.
    proportion_cv : float
        Spread of segment lengths relative to stature (coefficient of variation).
    segments : tuple of (str, str)
        Pairs on one bone: their distance stays fixed (up to skin movement).
    hinge_segments : tuple of (str, str)
        Pairs across a hinge whose axis passes through one of the markers (knee marker to
        ankle marker, ...): nearly fixed distances.
    mirror : tuple of (str, str)
        (left, right) pairs, mirror images across the sagittal plane (Y = 0).
    midline : tuple of str
        Markers on the sagittal plane.
    roles : mapping
        ``"pelvis"`` -> pelvis markers; ``"left"`` / ``"right"`` -> mapping of ``"heel"``,
        ``"toe"``, ``"ankle"`` to marker names (those present in ``names``).
    aliases : mapping
        Other names for the same landmarks (another lab's labels) -> names of this set.
    height_mm, reference_height_mm : float
        Stature the template is drawn for, and the stature of the shipped data.
    frame, source, description : str
    """

    name: str
    names: tuple[str, ...]
    template_mm: NDArray[np.float64]
    sd_mm: NDArray[np.float64]
    placement_sd_mm: NDArray[np.float64]
    proportion_cv: float = 0.03
    segments: tuple[Pair, ...] = ()
    hinge_segments: tuple[Pair, ...] = ()
    mirror: tuple[Pair, ...] = ()
    midline: tuple[str, ...] = ()
    roles: Mapping[str, object] = field(default_factory=lambda: MappingProxyType({}))
    aliases: Mapping[str, str] = field(default_factory=lambda: MappingProxyType({}))
    height_mm: float = 1750.0
    reference_height_mm: float = 1750.0
    frame: str = ""
    source: str = ""
    description: str = ""

    def __post_init__(self) -> None:
        n = len(self.names)
        if self.template_mm.shape != (n, 3) or self.sd_mm.shape != self.placement_sd_mm.shape:
            raise ValueError("template_mm must be (n, 3) and the SDs (n,) for n names")
        for arr in (self.template_mm, self.sd_mm, self.placement_sd_mm):
            arr.setflags(write=False)

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Row of marker ``name`` (an alias is accepted); one-line error if unknown."""
        name = self.aliases.get(name, name)
        if name not in self.names:
            raise InputError(f"marker set {self.name!r}: {unknown_message(name, self.names)}")
        return self.names.index(name)

    def position(self, name: str) -> NDArray[np.float64]:
        """Template position (mm) of one marker."""
        return self.template_mm[self.index(name)]

    def scaled(self, height_mm: float) -> MarkerSet:
        """The set drawn for a subject of ``height_mm`` (isometric scaling of template and SD).

        Winter 2009 gives segment lengths as constant fractions of stature, so positions
        relative to the floor origin scale with it; so does the between-subject spread.
        """
        if not np.isfinite(height_mm) or not 500.0 <= height_mm <= 2500.0:
            raise InputError(f"subject height must be 500-2500 mm, got {height_mm!r}")
        k = height_mm / self.height_mm
        return replace(
            self,
            template_mm=self.template_mm * k,
            sd_mm=self.sd_mm * k,
            placement_sd_mm=self.placement_sd_mm * k,
            height_mm=float(height_mm),
        )

    def segment_lengths_mm(self, hinge: bool = False) -> dict[Pair, float]:
        """Template distance of every segment pair (``hinge`` adds the hinge pairs)."""
        pairs = self.segments + (self.hinge_segments if hinge else ())
        return {
            (a, b): float(np.linalg.norm(self.position(a) - self.position(b))) for a, b in pairs
        }

    def segment_sd_mm(self, hinge: bool = False) -> dict[Pair, float]:
        """Plausible spread of each segment length across subjects of this height.

        The two markers' placement SDs and ``proportion_cv`` of the length, in quadrature.
        """
        sd = dict(zip(self.names, self.placement_sd_mm, strict=True))
        return {
            (a, b): float(np.sqrt(sd[a] ** 2 + sd[b] ** 2 + (self.proportion_cv * d) ** 2))
            for (a, b), d in self.segment_lengths_mm(hinge).items()
        }

    def mirror_of(self, name: str) -> str | None:
        """The other side's marker of a mirror pair, ``name`` itself on the midline, else None."""
        name = self.names[self.index(name)]
        for left, right in self.mirror:
            if name == left:
                return right
            if name == right:
                return left
        return name if name in self.midline else None

    def foot(self, side: str) -> dict[str, str]:
        """Heel, toe and ankle marker names of ``side`` (``"left"`` / ``"right"``)."""
        if side not in ("left", "right"):
            raise InputError(f"side must be 'left' or 'right', got {side!r}")
        return dict(self.roles.get(side, {}))

    @property
    def pelvis(self) -> tuple[str, ...]:
        """The set's pelvis markers present in ``names``."""
        return tuple(self.roles.get("pelvis", ()))

    def select(self, names: tuple[str, ...] | list[str]) -> MarkerSet:
        """The set restricted to ``names`` (in that order; aliases accepted)."""
        names = tuple(self.aliases.get(n, n) for n in names)
        rows = [self.index(n) for n in names]
        seen = set()
        for n in names:
            if n in seen:
                raise InputError(f"marker set {self.name!r}: marker {n!r} given twice")
            seen.add(n)
        keep = set(names)

        def pairs(ps: tuple[Pair, ...]) -> tuple[Pair, ...]:
            return tuple((a, b) for a, b in ps if a in keep and b in keep)

        roles: dict[str, object] = {"pelvis": tuple(n for n in self.pelvis if n in keep)}
        for side in ("left", "right"):
            roles[side] = MappingProxyType({k: v for k, v in self.foot(side).items() if v in keep})
        return replace(
            self,
            names=names,
            template_mm=self.template_mm[rows].copy(),
            sd_mm=self.sd_mm[rows].copy(),
            placement_sd_mm=self.placement_sd_mm[rows].copy(),
            segments=pairs(self.segments),
            hinge_segments=pairs(self.hinge_segments),
            mirror=pairs(self.mirror),
            midline=tuple(n for n in self.midline if n in keep),
            roles=MappingProxyType(roles),
        )


def unknown_message(name: str, known: tuple[str, ...] | list[str], what: str = "marker") -> str:
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.5)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"unknown {what} {name!r}{hint}"
