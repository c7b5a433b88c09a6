"""Claims of the lessons' prose, computed and asserted where they are made.

A lesson states what holds with margin ("halving h shrinks the band by about four") and backs
the sentence with a code cell that computes it::

    from mslab.claims import claim
    claim("halving h shrinks leapfrog's band by about 2^2", 3.0 < ratio < 5.0, ratio=f"{ratio:.1f}")

The cell prints the statement with the numbers it rests on; when the statement is false the
cell fails (``ClaimError``), so nbval catches prose that a change of the library made wrong.
Numbers are printed as given: pass strings formatted to the digits the statement needs (a
float is printed with three significant digits), so the stored output does not depend on
round-off.

Each claim may carry an ``id``; a markdown sentence names it with an invisible HTML comment
``<!-- claim: ID -->`` and ``tools/lessons_check.py`` lists the sentences with numbers or
verdict words that no claim backs.
"""

from __future__ import annotations

from numbers import Integral, Real

__all__ = ["ClaimError", "claim"]


class ClaimError(AssertionError):
    """A lesson's claim that its own computation contradicts."""


def _show(value: object) -> str:
    if isinstance(value, bool) or isinstance(value, Integral):
        return str(value)
    if isinstance(value, Real):
        return f"{float(value):.3g}"
    return str(value)


def claim(statement: str, holds: bool, *, id: str | None = None, **numbers: object) -> None:  # noqa: A002
    """Print ``statement`` with the numbers it rests on; raise ``ClaimError`` when it is false.

    Parameters
    ----------
    statement : str
        The sentence of the prose, as the student reads it.
    holds : bool
        Its computed truth value (a numpy bool is accepted).
    id : str, optional
        The name that the markdown's ``<!-- claim: ID -->`` comment uses.
    **numbers
        The values the statement rests on, printed as ``name = value`` (strings as given,
        floats to three significant digits).
    """
    shown = ", ".join(f"{name} = {_show(value)}" for name, value in numbers.items())
    tag = f"[{id}] " if id else ""
    line = f"{tag}{statement}" + (f"  ({shown})" if shown else "")
    if not bool(holds):
        raise ClaimError(f"claim false: {line}")
    print(f"claim holds: {line}")
