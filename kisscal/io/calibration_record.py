"""The calibration's comparison documents, typed: ``lens_models`` and ``dlt/wand.json``.

``lens_models`` (in each ``dlt/<camera>.json``) compares the camera models on held-out
points; ``dlt/wand.json`` holds the wand adjustment's figures (DESIGN.md). Each is read
once from its JSON form into a frozen record; the summary and the report go through
these records, never the raw dicts.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from kisscal.io.files import lookup

#: A value of a JSON document shown as it is (a number, a word, a yes/no).
Scalar = int | float | str | bool
#: ``dlt/wand.json`` groups whose numbers are wand figures too (named ``<group>_<key>``).
WAND_GROUPS = (
    "held_out",
    "held_out_rods_alone",
    "held_out_rod_markers",
    "rods_weight_fits",
    "axes",
)


def _number(value: Any) -> int | float | None:
    """``value`` when it is a number (not a yes/no), as it is; else None."""
    return value if isinstance(value, int | float) and not isinstance(value, bool) else None


def _numbers(cls: type, doc: Mapping[str, Any]) -> dict[str, int | float | None]:
    """The numbers of ``doc`` named as the fields of dataclass ``cls`` that hold one."""
    kinds = ("float | None", "int | None")
    return {f.name: _number(doc.get(f.name)) for f in fields(cls) if f.type in kinds}


@dataclass(frozen=True)
class ModelScore:
    """One camera model judged on the points its fits left out (None: not measured)."""

    model: str
    held_out_rms_px: float | None
    held_out_3d_rms_mm: float | None


@dataclass(frozen=True)
class LensModels:
    """A camera's models compared (``lens_models`` of ``dlt/<camera>.json``).

    Attributes
    ----------
    chosen : str
        The model the calibration kept.
    by : str
        What decided (``"held-out 3D error"`` or ``"held-out reprojection error"``).
    folds : int
        How many subsets of the control points were left out in turn.
    models : mapping of str -> ModelScore
        Each model compared, in the document's order.
    """

    chosen: str
    by: str
    folds: int
    models: Mapping[str, ModelScore]

    @classmethod
    def read(cls, doc: Mapping[str, Any] | None) -> LensModels | None:
        """The comparison in a camera's DLT document (None when it has none)."""
        entry = lookup(doc, "lens_models")
        if not isinstance(entry, Mapping) or "models" not in entry:
            return None
        models = {
            str(m): ModelScore(str(v.get("model", m)), **_numbers(ModelScore, v))
            for m, v in entry["models"].items()
        }
        return cls(
            str(entry["chosen"]), str(entry.get("by", "")), int(entry.get("folds", 0)), models
        )

    def held_out_rms_px(self, model: str) -> float | None:
        """The held-out reprojection error of ``model`` (None when it was not compared)."""
        score = self.models.get(model)
        return score.held_out_rms_px if score is not None else None


@dataclass(frozen=True)
class WandRecord:
    """``dlt/wand.json``, typed.

    Attributes
    ----------
    figures : tuple of (str, int or float)
        Every number of the document in its order, those of :data:`WAND_GROUPS` named
        ``<group>_<key>`` (wand length, held-out length, iterations, axes fit, ...).
    kept : str
        ``"wand"``, or ``"rods"`` when the wand did not lower the held-out error.
    cameras : mapping of str -> mapping of str -> Scalar
        Each camera's figures (residual, points, coverage, intrinsics, lens terms).
    rods_weighed : str
        On the rods with trials, the rods' weight kept (``own_noise`` or ``rods_route``;
        both fits' figures are in ``rods_weight_fits``); "" otherwise.
    """

    figures: tuple[tuple[str, int | float], ...]
    kept: str
    cameras: Mapping[str, Mapping[str, Scalar]]
    rods_weighed: str = ""

    @classmethod
    def read(cls, doc: Any) -> WandRecord | None:
        """The record of a ``wand.json`` document (None when there is none)."""
        if not isinstance(doc, Mapping) or not doc:
            return None
        figures = [(str(k), x) for k, v in doc.items() if (x := _number(v)) is not None]
        for group in WAND_GROUPS:
            sub = doc.get(group)
            if isinstance(sub, Mapping):
                figures += [
                    (f"{group}_{k}", x) for k, v in sub.items() if (x := _number(v)) is not None
                ]
        per_cam = doc.get("cameras") or doc.get("per_camera") or {}
        cameras = {
            str(c): {str(k): v for k, v in d.items() if isinstance(v, Scalar)}
            for c, d in (per_cam.items() if isinstance(per_cam, Mapping) else ())
            if isinstance(d, Mapping)
        }
        weighed = str(doc.get("rods_weighed", ""))
        return cls(tuple(figures), str(doc.get("kept", "")), cameras, weighed)

    @property
    def camera_columns(self) -> tuple[str, ...]:
        """The figures of :attr:`cameras`, each once, in order of first appearance."""
        keys = (k for d in self.cameras.values() for k in d if k != "camera")
        return tuple(dict.fromkeys(keys))


@dataclass(frozen=True)
class TargetMatchRecord:
    """The figures of one camera's match of the known target (None: not in the document):
    a record of the match, not a camera model."""

    visible: int | None
    matched: int | None
    unmatched: int
    rms_px: float | None
    seed_rms_px: float | None
    written_rms_px: float | None = None  # the calibration written (its DLT); older: none


@dataclass(frozen=True)
class TargetRecord:
    """``dlt/target.json``, typed: the target points each camera saw and matched.

    Attributes
    ----------
    cameras : mapping of str -> TargetMatchRecord
        Each camera's visible and matched points and its reprojection errors.
    """

    cameras: Mapping[str, TargetMatchRecord]

    @classmethod
    def read(cls, doc: Any) -> TargetRecord | None:
        """The record of a ``target.json`` document (None when it matched no camera)."""
        cams = lookup(doc, "cameras")
        if not isinstance(cams, Mapping) or not cams:
            return None
        return cls(
            {
                str(c): TargetMatchRecord(
                    unmatched=len(e.get("unmatched") or ()), **_numbers(TargetMatchRecord, e)
                )
                for c, e in cams.items()
                if isinstance(e, Mapping)
            }
        )
