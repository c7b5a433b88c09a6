"""The numbers a public test expects, read from ``expected.json`` beside it.

A public test ships with the student release, so it must not compute an answer in the
exercise's own form: the few lines that would give the right answer, or a known mistake's
answer that is the right one with a sign flipped, would be the solution. Such answers are
computed on the instructor's side, by ``tools/exercise_expected.py`` from the keys in
``tools/exercise_keys/`` (neither is in the package or the release), and stored as plain
numbers. A public test reads them::

    EXPECTED = Expected(__file__)
    right, wrong = EXPECTED.arrays("small_net")      # tuples of arrays, {hint: tuple}
    check_known((f,), right, wrong, whats=("forces",))

Answers the library computes through its public API (``reference_run``, ``Springs.force``)
are still computed in the test: the library is the course's open workbench, and a graded
file cannot import it.

The file holds JSON only (nothing that is executed or expanded). Its format: a case name ->
``{"expected": [value, ...], "mistakes": {hint: [value, ...]}}``, where each value is a
number, a nested list of numbers (an array), or ``{"re": array, "im": array}`` (a complex array).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

FILE = "expected.json"


def _value(a: object) -> float | np.ndarray:
    if isinstance(a, int | float):
        return float(a)
    if isinstance(a, dict):  # a complex array: {"re": [...], "im": [...]}
        return np.array(a["re"], dtype=float) + 1j * np.array(a["im"], dtype=float)
    return np.array(a, dtype=float)


def _values(items: list, where: str) -> tuple:
    if not isinstance(items, list):
        raise ValueError(f"{where}: expected a list of values")
    return tuple(_value(a) for a in items)


class Expected:
    """The stored answers of one exercise's public tests (``expected.json`` beside ``test_file``)."""

    def __init__(self, test_file: str | Path):
        self.path = Path(test_file).with_name(FILE)
        self._cases: dict | None = None

    def _case(self, name: str) -> dict:
        if self._cases is None:
            try:
                self._cases = json.loads(self.path.read_text(encoding="utf-8"))
            except FileNotFoundError:
                raise FileNotFoundError(f"{self.path.name} is missing beside the tests: keep the exercise's "
                                        f"folder as it was handed out") from None
        if name not in self._cases:
            raise KeyError(f"{self.path.name}: no case {name!r}")
        return self._cases[name]

    def arrays(self, name: str) -> tuple[tuple, dict[str, tuple]]:
        """Return ``(expected, {hint: a mistake's answer})`` of case ``name``, each a tuple of values."""
        case = self._case(name)
        where = f"{self.path.name}: {name}"
        return (_values(case.get("expected", []), where),
                {hint: _values(v, f"{where}: {hint}") for hint, v in case.get("mistakes", {}).items()})

    def scalar(self, name: str) -> tuple[float, dict[str, float]]:
        """Return ``(expected, {hint: a mistake's answer})`` of a case whose answers are one number each."""
        right, wrong = self.arrays(name)
        if len(right) != 1 or not isinstance(right[0], float):
            raise ValueError(f"{self.path.name}: {name}: not one number")
        return right[0], {hint: float(w[0]) for hint, w in wrong.items()}
