"""Which side of a comparison each subject is on: a lesson's sentence against its claims' statements.

A comparison in a sentence ("Radau IIA damps more than SDIRK2", "Heun's error is about 2000
times RK4's", "lumping the mass does better") names its subjects around a *pivot* word. The
claim's statement, which the code cell holds true, names them too. ``tools/lessons_check.py``
lists a sentence whose subjects sit around a pivot in the reverse order of every statement
that uses the same pivot with the same subjects (``reversed_comparisons``), or, where the
sentence names one subject before a comparative word, a different one than the statement does.

Subjects are the registered methods' names, written as the lessons write them ("symplectic
Euler", "Radau IIA", ``rk4``), and the few other things the lessons compare (``SUBJECTS``).
"""

from __future__ import annotations

import re

__all__ = ["PIVOTS", "SUBJECTS", "subjects_around", "reversed_comparisons"]

#: words that put one subject against another: comparatives, "more/less than", a ratio's "times"
PIVOTS = (r"faster|slower|cheaper|dearer|costlier|more accurate|less accurate|better|worse|larger|smaller|"
          r"higher|lower|greater|more than|less than|times")
#: the lessons' other compared things, written once: pattern -> subject
SUBJECTS = {r"lump(?:ed|ing)": "lumped", r"equal(?= mass)": "equal"}
#: how far (characters) a subject may stand from its pivot
REACH = 80


def _aliases() -> list[tuple[re.Pattern, str]]:
    from mslab.integrators import methods

    pairs = [(re.escape(name).replace("_", "[ _–-]"), name) for name in methods()]
    pairs += [(r"forward[ _–-]euler", "euler"), (r"radau[ _–-]iia", "radau_iia2"),
              (r"velocity[ _–-]verlet", "velocity_verlet")]
    pairs += list(SUBJECTS.items())
    pairs.sort(key=lambda p: -len(p[0]))       # "symplectic euler" before "euler"
    return [(re.compile(rf"\b(?:{pattern})(?:'s)?\b", re.IGNORECASE), name) for pattern, name in pairs]


def _subjects(text: str) -> list[tuple[int, int, str]]:
    """(start, end, subject) of every subject of ``text``, the longest name where two overlap."""
    found: list[tuple[int, int, str]] = []
    for pattern, name in _aliases():
        for m in pattern.finditer(text):
            if not any(s < m.end() and m.start() < e for s, e, _ in found):
                found.append((m.start(), m.end(), name))
    return sorted(found)


def subjects_around(text: str) -> list[tuple[str, str | None, str | None]]:
    """(pivot, nearest subject before it, nearest subject after it) for every pivot of ``text``."""
    subjects = _subjects(text)
    out = []
    for m in re.finditer(rf"\b(?:{PIVOTS})\b", text, re.IGNORECASE):
        before = [s for s in subjects if m.start() - REACH <= s[1] <= m.start()]
        after = [s for s in subjects if m.end() <= s[0] <= m.end() + REACH]
        out.append((" ".join(m.group(0).lower().split()), before[-1][2] if before else None,
                    after[0][2] if after else None))
    return out


def reversed_comparisons(sentence: str, statements: list[str]) -> list[str]:
    """Return the comparisons of ``sentence`` that its claims' ``statements`` make the other way round.

    Where the sentence names a subject on one side only, a comparative word ("better", not "more
    than" or "times", whose other side varies) must have the same subject as the statement's.
    """
    told = [c for s in statements for c in subjects_around(s)]
    problems = []
    for pivot, a, b in subjects_around(sentence):
        same = [(x, y) for p, x, y in told if p == pivot]
        if a and b and a != b and (b, a) in same and (a, b) not in same:
            problems.append(f"'{pivot}': the sentence puts {a} before {b}, its claim {b} before {a}")
        elif (a and not b and " " not in pivot and pivot != "times" and same
              and all(x and x != a for x, _ in same)):
            problems.append(f"'{pivot}': the sentence says it of {a}, its claim of {same[0][0]}")
    return problems
