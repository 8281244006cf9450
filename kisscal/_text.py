"""Words of the messages: counts with their noun in the right number."""

from __future__ import annotations

_IRREGULAR = {"trajectory": "trajectories", "was": "were", "is": "are", "has": "have"}


def plural(n: int, noun: str) -> str:
    """``n`` and ``noun``, the noun in the plural unless ``n`` is 1.

    >>> plural(1, "trajectory"), plural(2, "trajectory"), plural(0, "piece")
    ('1 trajectory', '2 trajectories', '0 pieces')
    """
    if n == 1:
        return f"{n} {noun}"
    return f"{n} {_IRREGULAR.get(noun, noun + 's')}"
