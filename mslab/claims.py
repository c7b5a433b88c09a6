"""Claims of the lessons' prose, computed and asserted where they are made.

A lesson states what holds with margin and backs the sentence with a code cell that computes
it and prints the values the sentence quotes::

    from mslab.claims import claim
    claim("halving h shrinks leapfrog's band about fourfold", 3.6 < ratio < 4.4, id="band",
          ratio=f"{ratio:.1f}")

The cell prints the statement with its values; when the statement is false the cell fails
(``ClaimError``), so nbval catches prose that a change of the library made wrong. Print
numbers as strings formatted to the digits the sentence quotes (a float is printed with three
significant digits), so the stored output does not depend on round-off.

A markdown sentence names a claim with an invisible ``<!-- claim: ID -->`` and
``tools/lessons_check.py`` compares the sentence with the claim's stored output: every number
of the sentence (``$...$`` included) must be one of the claim's printed values (or be bounded by
them: "more than 70", "about 30 %", "3-5"), every magnitude word (``MAGNITUDES``: "several",
"tens", "twice", ...) must fit one of them, every share word (``FRACTIONS``: "a fifth", "most
of", ...) a printed share, and every verdict word (``VERDICTS``: "faster",
"only", "never", ...) must appear in the claim's statement. This module holds those meanings,
written once, and the number reading both sides share.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from numbers import Integral, Real

__all__ = ["ClaimError", "claim", "MAGNITUDES", "FRACTIONS", "share_range", "VERDICTS", "NO_CLAIM_REASONS",
           "Number", "numbers_in", "normalise", "Printed", "parse_printed", "fits", "UNITS", "unit_at",
           "comparable", "in_base"]


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
        The sentence of the prose, as the student reads it; it must contain the verdict words
        ("faster", "only", ...) of the markdown sentences that name it.
    holds : bool
        Its computed truth value (a numpy bool is accepted).
    id : str, optional
        The name that the markdown's ``<!-- claim: ID -->`` comment uses.
    **numbers
        The values the statement rests on, printed as ``name = value`` (strings as given,
        floats to three significant digits); every number of the markdown sentence is compared
        with these.
    """
    shown = ", ".join(f"{name} = {_show(value)}" for name, value in numbers.items())
    tag = f"[{id}] " if id else ""
    line = f"{tag}{statement}" + (f"  ({shown})" if shown else "")
    if not bool(holds):
        raise ClaimError(f"claim false: {line}")
    print(f"claim holds: {line}")


# ---------------------------------------------------------------------------------------------
# The meanings the checker applies, written once.

#: Magnitude words: a sentence that uses one needs a printed value of its claim in the range
#: (lo, hi) (both ends included). Ratios read either way ("halves": 0.5 or 2). Actions on an
#: input ("halving h", "doubling n") are no magnitude words.
MAGNITUDES: dict[str, tuple[tuple[float, float], ...]] = {
    r"a few|few-percent": ((2.0, 5.0),),
    r"several": ((3.0, 9.0),),
    r"dozens?|tens": ((10.0, 99.0),),
    r"hundreds": ((100.0, 999.0),),
    r"thousands": ((1e3, 9999.0),),
    r"millions": ((1e6, 1e9 - 1),),
    r"an order of magnitude": ((5.0, 20.0), (0.05, 0.2)),
    r"orders of magnitude": ((100.0, math.inf), (0.0, 0.01)),
    r"twice|doubles|doubled|two-?fold": ((1.8, 2.2), (0.45, 0.556)),
    r"halves|halved|half(?= the| as)": ((1.8, 2.2), (0.45, 0.556)),
    r"thrice|triples?|tripled|three-?fold": ((2.7, 3.3), (0.303, 0.37)),
    r"quarters|quartered|four-?fold": ((3.6, 4.4), (0.227, 0.278)),
}


def share_range(share: float) -> tuple[float, float]:
    """Give the two-sided meaning (lo, hi) of a share word of nominal value ``share``.

    A share up to one half is read within 10 % as a factor, like "twice" (1.8-2.2): "a fifth"
    is 1/5.5-1/4.5. A larger share is read by its complement the same way (two thirds kept = a
    third lost: 0.630-0.697), so "nine in ten" never admits all.
    """
    if share <= 0.5:
        return share / 1.1, share / 0.9
    lo, hi = share_range(1.0 - share)
    return 1.0 - hi, 1.0 - lo


_SHARE_WORDS = {
    r"(?:a|one)[ -]half|half(?= of\b| its\b| their\b)|one in two": 1 / 2,
    r"(?:a|one)[ -]third|one in three": 1 / 3,
    r"two[ -]thirds|two in three": 2 / 3,
    r"(?:a|one)[ -]quarter|one in four": 1 / 4,
    r"three[ -]quarters|three in four": 3 / 4,
    r"(?:a|one)[ -]fifth|one in five": 1 / 5,
    r"two[ -]fifths|two in five": 2 / 5,
    r"three[ -]fifths|three in five": 3 / 5,
    r"four[ -]fifths|four in five": 4 / 5,
    r"(?:a|one)[ -]tenth|one in ten": 1 / 10,
    r"nine[ -]tenths|nine in ten": 9 / 10,
}

#: Share words (fractions and proportions): a sentence that uses one needs a printed value of its
#: claim, read as a share (a value in 0-1, or a percent printed with "%"), in the range (lo, hi);
#: a bound in front bounds the share by its nominal value ("more than half": above 0.5, "less than
#: a third": below 1/3, "half of it or more": at least 0.5). Entries: (nominal, lo, hi).
FRACTIONS: dict[str, tuple[float, float, float]] = {
    **{words: (share, *share_range(share)) for words, share in _SHARE_WORDS.items()},
    r"most(?= of\b)|the majority|a majority": (0.5, 0.5, 1.0),
    r"a minority": (0.5, 0.0, 0.5),
}

#: Words of a verdict (comparatives, superlatives, absolutes, qualitative outcomes): a sentence
#: backed by a claim must find each in the statement of one of its claims.
VERDICTS = (
    r"bounded|unbounded|drift(?:s|ing|ed)?|stable|unstable|blows? up|grows?|shrinks?|"
    r"faster|slower|cheaper|dearer|costlier|more accurate|less accurate|better|worse|"
    r"larger|smaller|higher|lower|fewer|greater|"
    r"fewest|least|most|best|worst|largest|smallest|highest|lowest|cheapest|fastest|"
    r"only|never|always|same|exactly|none"
)

#: Reasons a sentence may give for carrying no claim (``<!-- no-claim: REASON -->``, optionally
#: ``REASON: free words``).
NO_CLAIM_REASONS = {
    "definition": "defines a term, a method or a quantity",
    "parameter": "states a chosen input (a scene's stiffness, a step, a tolerance)",
    "pointer": "points to another lesson, the lecture notes, an exercise or a tool",
    "derivation-above": "repeats what the cell above derives symbolically or exactly",
    "convention": "a naming or sign convention",
    "outline": "what the lesson or a section will do",
    "question": "asks the student to predict or to try",
    "theorem": "a mathematical result cited from the lecture notes or the literature",
}

# ---------------------------------------------------------------------------------------------
# Reading numbers.

_SUPER = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹⁻", "0123456789-")
_NUM = r"\d+(?:\.\d+)?"
_TIMES_TEN = re.compile(
    rf"(?:({_NUM})\s*(?:×|\\times|\\cdot|·)\s*)?10(?:\^\{{?([-−]?\d+)\}}?|([⁻]?[⁰¹²³⁴⁵⁶⁷⁸⁹]+))")
_NUMBER = re.compile(
    rf"(?<![\w.])(?:(√|\\sqrt\s*\{{?\s*)({_NUM})\}}?|(\\t?frac\s*\{{?(\d+)\}}?\s*\{{?(\d+)\}}?)|"
    rf"({_NUM})\s*/\s*(\d+)(?![\w.])|({_NUM}(?:[eE][-+−]?\d+)?))(?![\w])")


@dataclass(frozen=True)
class Number:
    """A number as written: its value, half a unit of its last digit, and its offsets."""

    value: float
    half_ulp: float
    start: int
    end: int
    text: str

    def matches(self, printed: float, printed_half_ulp: float) -> bool:
        """Whether this number and a printed one round from a common value."""
        return abs(self.value - printed) <= self.half_ulp + printed_half_ulp + 1e-12 * abs(printed)


def _half_ulp(mantissa: str, exponent: int = 0) -> float:
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 0.5 * 10.0 ** (exponent - decimals)


_WORDS = {"two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8, "nine": 9, "ten": 10,
          "eleven": 11, "twelve": 12, "twenty": 20, "fifty": 50, "hundred": 100}
#: a number written as a word counts where it is a factor: "seven times", "threefold", "a factor of three"
_WORD = "|".join(_WORDS)
_FACTOR_WORD = re.compile(rf"(?<=factor of )({_WORD})\b|\b({_WORD})(?=-? ?(?:times\b|fold\b)|- to)",
                          re.IGNORECASE)
_TIMES_ROOT = re.compile(r"(?<![\w.])(\d+)\s*(?:\\sqrt\s*\{?\s*|√)(\d+)\}?")


def normalise(text: str) -> str:
    r"""Write ``a × 10^b`` and ``10⁻⁶`` as ``aeb``, ``2\sqrt 2`` as ``2.828...``.

    A number word that is a factor ("seven times", "threefold", "a factor of three") becomes its digits.
    To the digits that fit: padded or cut to the original length, so offsets stay.
    """
    def sub(m: re.Match) -> str:
        exp = (m.group(2) or m.group(3) or "").translate(_SUPER).replace("−", "-")
        new = f"{m.group(1) or '1'}e{exp}"
        return new + " " * max(0, len(m.group(0)) - len(new))

    def root(m: re.Match) -> str:
        value = float(m.group(1)) * math.sqrt(float(m.group(2)))
        digits = max(1, len(m.group(0)) - len(str(int(value))) - 1)
        return f"{value:.{digits}f}".ljust(len(m.group(0)))
    def word(m: re.Match) -> str:
        if m.group(0).lower() in ("two", "three", "four") and re.match(r"-?fold", m.string[m.end():]):
            return m.group(0)                                 # twofold ... fourfold: magnitude words
        return str(_WORDS[m.group(0).lower()]).ljust(len(m.group(0)))
    return _FACTOR_WORD.sub(word, _TIMES_ROOT.sub(root, _TIMES_TEN.sub(sub, text)))


def numbers_in(text: str) -> list[Number]:
    r"""Read the numbers of ``text``.

    Decimals, ``1e-6``, ``2 × 10⁻³``, ``10^{-4}``, ``√6``, ``1/2``, ``\frac{1}{2}``; signs are
    dropped (values are compared by magnitude).
    """
    found = []
    for m in _NUMBER.finditer(normalise(text)):
        if m.group(2):                                        # √a
            value, half = math.sqrt(float(m.group(2))), 0.0
        elif m.group(3):                                      # \frac{a}{b}
            value, half = float(m.group(4)) / float(m.group(5)), 0.0
        elif m.group(6):                                      # a/b
            value, half = float(m.group(6)) / float(m.group(7)), 0.0
        else:
            mant, _, exp = m.group(8).replace("E", "e").partition("e")
            exponent = int(exp.replace("−", "-")) if exp else 0
            value, half = float(mant) * 10.0 ** exponent, _half_ulp(mant, exponent)
        found.append(Number(value, half, m.start(), m.end(), m.group(0)))
    return found


#: Units a number can carry, by dimension and factor to the dimension's base; a count noun
#: ("6 steps") is a unit of its own. A sentence's number with a unit is compared only with
#: printed values of the same dimension (when its claims print any), converted.
UNITS: dict[str, tuple[str, float]] = {
    "s": ("s", 1.0), "ms": ("s", 1e-3), "µs": ("s", 1e-6), "us": ("s", 1e-6), "min": ("s", 60.0),
    "m": ("m", 1.0), "cm": ("m", 1e-2), "mm": ("m", 1e-3), "µm": ("m", 1e-6), "km": ("m", 1e3),
    "J": ("J", 1.0), "N": ("N", 1.0), "N/m": ("N/m", 1.0), "kg": ("kg", 1.0), "kg/s": ("kg/s", 1.0),
    "rad/s": ("rad/s", 1.0), "Hz": ("Hz", 1.0), "%": ("%", 1.0),
    "step": ("steps", 1.0), "steps": ("steps", 1.0), "iteration": ("iterations", 1.0),
    "iterations": ("iterations", 1.0), "evaluation": ("evaluations", 1.0),
    "evaluations": ("evaluations", 1.0), "times": ("times", 1.0),
}
_NOUNS = ("steps", "iterations", "evaluations", "times")
# a count noun may follow one word ("4.7 Newton iterations", "3201 force evaluations")
_PHYSICAL = "|".join(sorted((re.escape(u) for u, (d, _) in UNITS.items() if d not in _NOUNS),
                           key=len, reverse=True))
_COUNTS = "|".join(u for u, (d, _) in UNITS.items() if d in _NOUNS)
_FUNCTION_WORD = r"(?!(?:in|of|the|per|more|fewer|than|and|or|to|at|on|for|by|with|a|an)\s)"
_UNIT = re.compile(rf"\s*(?:({_PHYSICAL})|(?:{_FUNCTION_WORD}[A-Za-z]+\s+)?({_COUNTS}))(?![\w/])")
#: what joins the numbers of one printed list that share the unit after the last: "20, 10, 5 ms"
_LIST_JOIN = re.compile(r"[\s,]*(?:\.\.\.?|…|and|to)?[\s,]*")


def unit_at(text: str, pos: int) -> str | None:
    """Return the dimension of the unit written right after offset ``pos`` of ``text`` (None: no unit)."""
    m = _UNIT.match(text, pos)
    return UNITS[m.group(1) or m.group(2)][0] if m else None


def _scale(text: str, pos: int) -> float:
    m = _UNIT.match(text, pos)
    return UNITS[m.group(1) or m.group(2)][1] if m else 1.0


def in_base(number: Number, text: str, unit_pos: int) -> Number:
    """Return ``number`` in the base unit of the unit written at ``unit_pos`` of ``text``."""
    scale = _scale(text, unit_pos)
    return Number(number.value * scale, number.half_ulp * scale, number.start, number.end, number.text)


@dataclass(frozen=True)
class Printed:
    """One stored ``claim holds`` line: its id, statement and printed values.

    ``shares`` are the values that read as a share of a whole: a value in 0-1 without a
    physical unit, or a percent (printed with ``%``) divided by 100. ``measured`` are the
    values that carry a unit (written after them, shared along a list "20, 10, 5 ms", or the
    value's name when that is a count noun: ``steps = 6, 6``, or a ratio: ``ratios = 5.4``,
    ``a_over_b = 63``, read as "times"): (dimension, value, half a unit of its last digit),
    both in the dimension's base unit.
    """

    id: str
    statement: str
    values: tuple[tuple[float, float], ...]      # (value, half a unit of its last digit)
    shares: tuple[tuple[float, float], ...] = ()
    measured: tuple[tuple[str, float, float], ...] = ()


_HOLDS = re.compile(r"^claim holds: \[([\w.\-]+)\] (.*)$", re.MULTILINE)
_NAME = re.compile(r"(?:^|,\s*)([A-Za-z_]\w*) = ")


def _measured(values: str) -> list[tuple[str | None, float, float]]:
    """(dimension or None, value, half ulp) of every number of a claim's printed values, in base units."""
    out = []
    names = list(_NAME.finditer(values))
    for k, name in enumerate(names):
        chunk = values[name.end():names[k + 1].start() if k + 1 < len(names) else len(values)]
        numbers = numbers_in(chunk)
        noun = name.group(1).lower().rpartition("_")[2]
        by_name = UNITS[noun][0] if noun in UNITS and noun.endswith("s") and noun != "times" else None
        if re.search(r"ratio|_over_|factor", name.group(1)):   # ratios = 5.4; rk4_over_heun = 63: "N times"
            by_name = "times"
        units: list[tuple[str | None, float]] = [(unit_at(chunk, n.end), _scale(chunk, n.end))
                                                 for n in numbers]
        for i in range(len(numbers) - 2, -1, -1):  # a list shares the unit written after its last number
            if units[i][0] is None and _LIST_JOIN.fullmatch(chunk[numbers[i].end:numbers[i + 1].start]):
                units[i] = units[i + 1]
        for n, (dim, scale) in zip(numbers, units, strict=True):
            out.append((dim or by_name, n.value * scale, n.half_ulp * scale))
    return out


def parse_printed(output: str) -> list[Printed]:
    """Read the claims of a cell's stored output."""
    claims = []
    for m in _HOLDS.finditer(output):
        statement, values = m.group(2), ""
        head, sep, tail = statement.rpartition("  (")
        if sep and tail.endswith(")") and re.match(r"[A-Za-z_]\w* = ", tail):
            statement, values = head, tail[:-1]
        measured = _measured(values)
        plain = re.sub(r"\b[A-Za-z_]\w* = ", " ", values)
        numbers = numbers_in(plain)
        dims = [d for d, _, _ in measured] if len(measured) == len(numbers) else [None] * len(numbers)
        scaled = [(n.value / 100, n.half_ulp / 100) if re.match(r"\s*(?:%|\\%)", plain[n.end:])
                  else (n.value, n.half_ulp) for n in numbers]
        shares = tuple((v, h) for (v, h), d in zip(scaled, dims, strict=True)
                       if v - h <= 1.0 and d in (None, "%", "times"))
        claims.append(Printed(m.group(1), statement, tuple((n.value, n.half_ulp) for n in numbers), shares,
                              tuple((d, v, h) for d, v, h in measured if d is not None)))
    return claims


def comparable(text: str, unit_pos: int, claims: list[Printed], values: tuple) -> tuple:
    """Return the values a number of ``text`` with its unit at ``unit_pos`` is compared with.

    Those of the unit's dimension (in base units) when the claims print any, else ``values``.
    """
    dim = unit_at(text, unit_pos)
    same = tuple((v, h) for p in claims for d, v, h in p.measured if d == dim) if dim else ()
    return same or values


def fits(kind: str, number: Number | None, lo_hi: tuple[float, float] | None,
         values: tuple[tuple[float, float], ...]) -> bool:
    """Whether one of ``values`` makes the prose true.

    ``kind`` is ``"equal"`` (the number as printed, to its digits), ``"about"`` (within 10 %),
    ``"above"`` / ``"below"`` (a printed value beyond the bound), ``"range"`` (``lo_hi``, each
    end to its digits) or ``"magnitude"`` (``lo_hi`` exactly).
    """
    for value, half in values:
        if kind == "equal" and number.matches(value, half):
            return True
        if kind == "about" and abs(value - number.value) <= 0.1 * number.value + half:
            return True
        if kind == "above" and value + half > number.value:
            return True
        if kind == "below" and value - half < number.value:
            return True
        if kind in ("range", "magnitude") and lo_hi[0] - half <= value <= lo_hi[1] + half:
            return True
    return False
