"""The nearest valid name for a misspelt one, shared by every layer's error messages."""

from __future__ import annotations

from collections.abc import Iterable


def closest(word: str, choices: Iterable[str]) -> str | None:
    """The valid name closest to ``word`` (or differing only in case), if any is close."""
    # Here, not at the top: only a wrong name needs it, and every node would load it at start.
    import difflib

    names = sorted(str(c) for c in choices)
    close = difflib.get_close_matches(word, names, n=1, cutoff=0.6)
    if close:
        return close[0]
    lowered = {n.lower(): n for n in names}
    return lowered.get(word.lower())
