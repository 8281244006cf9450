"""``out/detection/<camera>.json``: a camera's derived detection settings, typed.

The document keeps, for each kind of image of a camera (``grid``, ``markers``), every
camera-dependent setting with its value, its source (``given`` in ``[detection]``,
``derived`` from the images, or the ``default``) and the reason, plus the grey levels
the survey measured and the key of what the settings were derived from. The session
writes it and reads it back to reuse settings an earlier run derived; the summary and the
report show it. All of them go through :class:`DetectionRecord`, never the raw JSON.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from kisscal.detect.configure import Choice, DetectionSetup
from kisscal.errors import InputError
from kisscal.io.files import read_json, write_json


@dataclass(frozen=True)
class KindRecord:
    """The settings of one kind of image of a camera, with what the survey measured.

    Attributes
    ----------
    settings : mapping of str -> Choice
        Every camera-dependent detection setting: its value, where it came from and why.
    key : str
        What the settings were derived from (given values, image size, derivation
        version); empty when unknown.
    frames_surveyed, bits : int
    background, noise_sigma, background_unevenness : float
        Grey levels measured (NaN when not recorded).
    marker_pixels : (int, int)
        Smallest and largest white-pixel count of the markers seen.
    notes : tuple of str
    """

    settings: Mapping[str, Choice]
    key: str = ""
    frames_surveyed: int = 0
    bits: int = 8
    background: float = math.nan
    noise_sigma: float = math.nan
    background_unevenness: float = math.nan
    marker_pixels: tuple[int, int] = (0, 0)
    notes: tuple[str, ...] = ()

    @classmethod
    def from_setup(cls, setup: DetectionSetup, key: str) -> KindRecord:
        """The record of a survey's result, keyed by what it was derived from."""
        lv = setup.levels
        return cls(
            settings=dict(setup.choices),
            key=key,
            frames_surveyed=setup.frames,
            bits=lv.bits,
            background=round(lv.background, 2),
            noise_sigma=round(lv.noise, 3),
            background_unevenness=round(lv.unevenness, 2),
            marker_pixels=tuple(setup.marker_pixels),
            notes=tuple(setup.notes),
        )

    def values(self, sources: tuple[str, ...] = ("given", "derived", "default")) -> dict:
        """Setting -> value, for the settings of the given sources (tuples as tuples)."""
        return {
            k: tuple(s.value) if isinstance(s.value, list) else s.value
            for k, s in self.settings.items()
            if s.source in sources
        }

    def source(self, name: str) -> str:
        """Where setting ``name`` came from (empty when the record does not hold it)."""
        setting = self.settings.get(name)
        return setting.source if setting is not None else ""

    def as_dict(self) -> dict[str, Any]:
        """The JSON form of this kind (DESIGN.md, ``out/detection/<camera>.json``)."""
        return {
            "frames_surveyed": self.frames_surveyed,
            "bits": self.bits,
            "background": self.background,
            "noise_sigma": self.noise_sigma,
            "background_unevenness": self.background_unevenness,
            "marker_pixels": list(self.marker_pixels),
            "settings": {
                k: {"value": _plain(s.value), "source": s.source, "why": s.why}
                for k, s in self.settings.items()
            },
            "notes": list(self.notes),
            "key": self.key,
        }


@dataclass(frozen=True)
class DetectionRecord:
    """A camera's detection settings per kind of image (``grid``, ``markers``)."""

    camera: str
    size: tuple[int, int] | None = None
    kinds: Mapping[str, KindRecord] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """The JSON document."""
        return {
            "camera": self.camera,
            "size": list(self.size) if self.size else None,
            "kinds": {k: r.as_dict() for k, r in self.kinds.items()},
        }


def _plain(value: Any) -> Any:
    if isinstance(value, tuple):
        return list(value)
    if isinstance(value, float):
        return round(value, 4)
    return value


def _kind(entry: Mapping[str, Any], where: str) -> KindRecord:
    settings = entry.get("settings", {})
    if not isinstance(settings, Mapping) or not all(
        isinstance(s, Mapping) and "value" in s for s in settings.values()
    ):
        raise InputError(f"{where}: each setting needs a value")
    band = entry.get("marker_pixels") or (0, 0)
    scalars = {
        f.name: type(f.default)(entry[f.name])
        for f in fields(KindRecord)
        if isinstance(f.default, int | float | str) and f.name in entry
    }
    return KindRecord(
        settings={
            k: Choice(s["value"], str(s.get("source", "given")), str(s.get("why", "")))  # type: ignore[arg-type]
            for k, s in settings.items()
        },
        marker_pixels=(int(band[0]), int(band[1])),
        notes=tuple(str(n) for n in entry.get("notes", ())),
        **scalars,
    )


def read_detection_record(path: Path) -> DetectionRecord | None:
    """The record at ``path``, or None when there is none.

    Raises
    ------
    InputError
        The file is there but is not JSON, or not a detection document.
    """
    doc = read_json(path)
    if doc is None:
        return None
    try:
        kinds = doc["kinds"]
        size = doc.get("size")
        return DetectionRecord(
            camera=str(doc.get("camera", path.stem)),
            size=(int(size[0]), int(size[1])) if size else None,
            kinds={k: _kind(e, f"{path} [{k}]") for k, e in kinds.items()},
        )
    except (ValueError, KeyError, TypeError, AttributeError, IndexError) as exc:
        raise InputError(f"{path}: not a detection settings document ({exc})") from None


def write_detection_record(
    path: Path,
    record: DetectionRecord,
    derived: Mapping[str, tuple[DetectionSetup, str]] | None = None,
) -> None:
    """Write ``record`` to ``path`` (atomically), with the settings ``derived`` for some
    kinds of image (a survey's result and the key of what it was derived from) in place
    of those it kept."""
    for kind, (setup, key) in (derived or {}).items():
        kinds = {**record.kinds, kind: KindRecord.from_setup(setup, key)}
        record = replace(record, kinds=kinds)
    write_json(path, record.as_dict())
