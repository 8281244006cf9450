"""Words of the messages: counts with their noun in the right number."""

from __future__ import annotations

_IRREGULAR = {"trajectory": "trajectories", "was": "were", "is": "are", "has": "have"}


def plural(n: int, noun: str, many: str | None = None) -> str:
    """``n`` and ``noun``, the noun in the plural unless ``n`` is 1.

    >>> plural(1, "trajectory"), plural(2, "trajectory"), plural(0, "piece")
    ('1 trajectory', '2 trajectories', '0 pieces')
    >>> plural(3, "field of view", "fields of view")
    '3 fields of view'
    """
    if n == 1:
        return f"{n} {noun}"
    return f"{n} {many or _IRREGULAR.get(noun, noun + 's')}"
