"""One base for every stage's parameters: defaults, units, bounds and one validator.

A stage declares its parameters as a frozen dataclass deriving from :class:`Params`, each
field made with :func:`param`, which records the default, the unit and the allowed range in
the field's metadata. Validation, copying with changes (:meth:`Params.replace`) and building
from ``session.toml`` / command-line layers (:meth:`Params.from_layers`) are written once,
here, so that every stage reports a bad value the same way: one line naming the section,
the parameter, what it must be, and what it got.

Example
-------
>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class ToyParams(Params):
...     section = "toy"
...     radius_px: float = param(2.0, unit="px", gt=0)
...     mode: str = param("fast", choices=("fast", "exact"))
>>> ToyParams().replace(radius_px=3).radius_px
3.0
>>> ToyParams(radius_px=-1)
Traceback (most recent call last):
...
kisscal.errors.InputError: [toy] radius_px must be > 0 px, got -1
"""

from __future__ import annotations

import dataclasses
import difflib
import types
import typing
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, Literal, TypeVar

import numpy as np

from kisscal.errors import InputError

P = TypeVar("P", bound="Params")

_NUMBER = (int, float, np.integer, np.floating)


def param(
    default: Any,
    *,
    unit: str = "",
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    choices: Sequence[Any] | None = None,
    odd: bool = False,
) -> Any:
    """A parameter field: its default, unit and allowed range (checked on construction).

    Parameters
    ----------
    default : object
        The one default of this parameter.
    unit : str
        Unit, as written after numbers in messages and docs (``"px"``, ``"mm"``, ``""``).
    ge, gt, le, lt : float, optional
        Bounds (``>=``, ``>``, ``<=``, ``<``); for tuples, every element is checked.
    choices : sequence, optional
        The allowed values (for text options).
    odd : bool
        Integers (or every element of a tuple of integers) must be odd.
    """
    meta = {"unit": unit, "ge": ge, "gt": gt, "le": le, "lt": lt, "choices": choices, "odd": odd}
    if isinstance(default, list | dict | set):
        raise TypeError("param defaults must be immutable (use a tuple)")
    return dataclasses.field(default=default, metadata={"kisscal": meta})


@dataclasses.dataclass(frozen=True)
class Params:
    """Base of the frozen parameter dataclasses of the stages.

    Subclasses set ``section`` (the ``session.toml`` table their values come from) and
    may override :meth:`check` for rules that tie several parameters together.
    """

    section: ClassVar[str] = "params"

    def __post_init__(self) -> None:
        hints = _hints(type(self))
        for f in dataclasses.fields(self):
            value = _coerce(self.section, f, hints[f.name], getattr(self, f.name))
            object.__setattr__(self, f.name, value)
        self.check()

    def check(self) -> None:
        """Rules between parameters; raise :class:`KisscalError` when one is broken."""

    def fail(self, message: str) -> typing.NoReturn:
        """Raise the one-line error of this section."""
        raise InputError(f"[{self.section}] {message}")

    def replace(self: P, **changes: Any) -> P:
        """A copy with ``changes``; an unknown name is an error with a did-you-mean."""
        _check_names(type(self), changes)
        return dataclasses.replace(self, **changes)

    @classmethod
    def from_layers(cls: type[P], *layers: Mapping[str, Any]) -> P:
        """Defaults, overridden by each mapping in turn (``session.toml``, then the CLI)."""
        values: dict[str, Any] = {}
        for layer in layers:
            values.update(layer)
        _check_names(cls, values)
        return cls(**values)


def _hints(cls: type) -> dict[str, Any]:
    cached = cls.__dict__.get("_kisscal_hints")
    if cached is None:
        cached = typing.get_type_hints(cls)
        type.__setattr__(cls, "_kisscal_hints", cached)
    return cached


def _check_names(cls: type, values: Mapping[str, Any]) -> None:
    names = [f.name for f in dataclasses.fields(cls)]
    for key in values:
        if key not in names:
            close = difflib.get_close_matches(key, names, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise InputError(f"[{cls.section}] unknown parameter {key!r}{hint}")


def _coerce(section: str, f: dataclasses.Field, hint: Any, value: Any) -> Any:
    """``value`` converted to the field's type (int -> float, list -> tuple) and checked."""
    meta = f.metadata.get("kisscal", {})
    unit = f" {meta['unit']}" if meta.get("unit") else ""

    def bad(what: str) -> typing.NoReturn:
        raise InputError(f"[{section}] {f.name} must be {what}, got {value!r}")

    kinds = _alternatives(hint)
    if value is None:
        if type(None) in kinds:
            return None
        bad(_describe(kinds))
    result = _convert(value, [k for k in kinds if k is not type(None)])
    if result is _BAD:
        bad(_describe(kinds))
    items = result if isinstance(result, tuple) else (result,)
    for item in items:
        _check_bounds(item, meta, unit, bad)
    return result


_BAD = object()


def _alternatives(hint: Any) -> list[Any]:
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return list(typing.get_args(hint))
    return [hint]


def _convert(value: Any, kinds: list[Any]) -> Any:
    for kind in kinds:
        converted = _convert_one(value, kind)
        if converted is not _BAD:
            return converted
    return _BAD


def _convert_one(value: Any, kind: Any) -> Any:
    origin = typing.get_origin(kind)
    if origin is Literal:
        return value if value in typing.get_args(kind) else _BAD
    if origin is tuple:
        args = typing.get_args(kind)
        if not isinstance(value, tuple | list | np.ndarray):
            return _BAD
        value = tuple(np.asarray(value).tolist()) if isinstance(value, np.ndarray) else value
        if len(args) == 2 and args[1] is Ellipsis:
            args = (args[0],) * len(value)
        if len(args) != len(value):
            return _BAD
        out = tuple(_convert_one(v, a) for v, a in zip(value, args, strict=True))
        return _BAD if any(o is _BAD for o in out) else out
    if kind is bool:
        return bool(value) if isinstance(value, bool | np.bool_) else _BAD
    if kind is int:
        ok = isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)
        return int(value) if ok else _BAD
    if kind is float:
        ok = isinstance(value, _NUMBER) and not isinstance(value, bool | np.bool_)
        return float(value) if ok and np.isfinite(value) else _BAD
    if kind is str:
        return value if isinstance(value, str) else _BAD
    if kind is Any:
        return value
    return value if isinstance(value, kind) else _BAD


def _describe(kinds: list[Any]) -> str:
    words = []
    for kind in kinds:
        origin = typing.get_origin(kind)
        if kind is type(None):
            words.append("unset")
        elif origin is Literal:
            words.append("one of " + ", ".join(repr(a) for a in typing.get_args(kind)))
        elif origin is tuple:
            args = typing.get_args(kind)
            n = "several" if len(args) == 2 and args[1] is Ellipsis else str(len(args))
            words.append(f"{n} {getattr(args[0], '__name__', 'value')}s")
        elif kind is float:
            words.append("a finite number")
        elif kind is int:
            words.append("a whole number")
        elif kind is bool:
            words.append("true or false")
        else:
            words.append(getattr(kind, "__name__", str(kind)))
    return " or ".join(words)


def _check_bounds(item: Any, meta: Mapping[str, Any], unit: str, bad: Any) -> None:
    if meta.get("choices") is not None and item not in meta["choices"]:
        bad("one of " + ", ".join(repr(c) for c in meta["choices"]))
    if not isinstance(item, _NUMBER) or isinstance(item, bool):
        return
    for key, word, holds in (
        ("ge", ">=", lambda a, b: a >= b),
        ("gt", ">", lambda a, b: a > b),
        ("le", "<=", lambda a, b: a <= b),
        ("lt", "<", lambda a, b: a < b),
    ):
        bound = meta.get(key)
        if bound is not None and not holds(item, bound):
            bad(f"{word} {bound:g}{unit}")
    if meta.get("odd") and int(item) % 2 != 1:
        bad("odd")
