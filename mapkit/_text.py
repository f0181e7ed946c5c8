"""Small helpers for the words of messages and reports."""

from __future__ import annotations

__all__ = ["plural"]


def plural(n: int, word: str, many: str | None = None) -> str:
    """``1 goal``, ``2 goals``, ``0 goals``; ``many`` for irregular words (``1 box``/``2 boxes``).

    Examples:
        >>> plural(1, "warning"), plural(3, "home"), plural(1, "forbidden area")
        ('1 warning', '3 homes', '1 forbidden area')
        >>> plural(2, "optimisation pass", "optimisation passes")
        '2 optimisation passes'
    """
    return f"{n} {word if n == 1 else (many or word + 's')}"
