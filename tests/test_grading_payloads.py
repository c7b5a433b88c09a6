"""The trust boundary (issue 35, item 1): student data is inert in the trusted runner.

Exercise 04's hidden test once handed the strings of a student's ``rk4_tableau()`` to
``ExplicitRK``, whose coefficient reader passed any text that was not a fraction to
``sympy.sympify``: Python ran as the grader (151/151 with nothing implemented). Here a
payload that would create a marker file if anything executed it is planted in every place
student data enters the runner (the return value of every function of all twelve
exercises, exception messages, strings, huge numbers, deep nesting, giant arrays): the
marker never appears and every test scores what the real implementation deserves.
"""

from __future__ import annotations

import textwrap
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from mslab.grading import find_exercises, grade
from mslab.grading.wire import WireError, dumps, loads
from mslab.integrators import ExplicitRK
from mslab.integrators.families.coefficients import as_fraction, parse_text, to_float

SOURCE = Path(__file__).resolve().parents[1] / "exercises"


def payload(marker: Path, value: str = "0.5") -> str:
    """Python (valid for ``eval`` and ``sympify``) that creates ``marker`` and is worth ``value``."""
    return f"__import__('pathlib').Path({str(marker)!r}).touch() or {value}"


# -- the library's coefficient reader -----------------------------------------------------------


def test_coefficient_text_is_never_executed(tmp_path):
    marker = tmp_path / "ran"
    with pytest.raises(ValueError, match="not a number"):
        ExplicitRK([[0, 0], [payload(marker), 0]], [0.5, 0.5])
    for text in (payload(marker), "exec('1')", "Symbol('x')", "x", "1/2 + y", "2**3", "pi"):
        with pytest.raises(ValueError):
            to_float(text)
        with pytest.raises(ValueError):
            as_fraction(text)
    assert not marker.exists()


def test_coefficient_text_is_bounded():
    # Fraction("1e10000000") builds a ten-million-digit integer (seconds of CPU): refused unread
    for text in ("1e10000000", "1e-10000000", "9" * 5000, "1" * 201, "(" * 40 + "1" + ")" * 40):
        with pytest.raises(ValueError):
            to_float(text)
        with pytest.raises(ValueError):
            as_fraction(text)


def test_coefficient_grammar_reads_what_the_library_documents():
    # the forms the library's methods and tests use, compared with independent arithmetic
    assert parse_text("19372/6561") == Fraction(19372, 6561)
    assert parse_text(" -0.25 ") == Fraction(-1, 4)
    assert parse_text("1e-3") == Fraction(1, 1000)
    assert parse_text("(1 + 2) * 3 / 4") == Fraction(9, 4)
    assert to_float("1 - sqrt(2)/2") == pytest.approx(1 - np.sqrt(2) / 2, rel=1e-15)
    assert to_float("1/sqrt(2)") == pytest.approx(np.sqrt(0.5), rel=1e-15)
    assert as_fraction("3/40") == (Fraction(3, 40), True)
    assert as_fraction("sqrt(2)")[1] is False
    rk = ExplicitRK([[0, 0], ["1/2", 0]], ["0", "1"])
    assert rk.A[1, 0] == 0.5 and list(rk.b) == [0.0, 1.0]


# -- the wire decoder ----------------------------------------------------------------------------


def test_wire_refuses_what_is_not_small_plain_data():
    assert loads(dumps({"a": [1, 2.5, "x", (3, None)], "z": np.arange(4.0)}))["z"].tolist() == [0, 1, 2, 3]
    refused = [
        b'{"__d__":{"v":' + b"9" * 5000 + b"}}",                      # an int of 5000 digits
        b'{"__d__":{"v":' + str(2**64).encode() + b"}}",             # beyond 64 bits
        b'{"__d__":{"v":"' + b"a" * 20000 + b'"}}',                  # a long string
        b'{"__d__":{"v":{"__nd__":["O",[1],"AAAAAAAAAAA="]}}}',         # an object array
        b'{"__d__":{"v":{"__nd__":["(2,)<f8",[1],"' + b"A" * 24 + b'"]}}}',  # a sub-array dtype
        b'{"__d__":{"v":{"__nd__":["<f8",[4294967296,4294967296,0],""]}}}',  # shape overflows int64
        b'{"__d__":{"v":{"__c__":["1e5",[2]]}}}',                     # a complex of strings
        b'{"__d__":{"v":{"__c__":[1.0]}}}',
    ]
    for line in refused:
        with pytest.raises(WireError):
            loads(line)


# -- the attack of the red team, through the grader ----------------------------------------------

RK_SOLUTION = (SOURCE / "04_rk4_tableau" / "rk_tableau.py").read_text()


def submit(folder: Path, exercise: str, module: str, text: str) -> Path:
    (folder / exercise).mkdir(parents=True)
    (folder / exercise / module).write_text(text)
    return folder


def test_tableau_strings_do_not_run_in_the_runner(tmp_path):
    # the reference rk_step (5 + 4 points deserved) and an rk4_tableau whose strings, evaluated, are RK4
    marker = tmp_path / "ran"
    values = [["0", "0", "0", "0"], ["0.5", "0", "0", "0"], ["0", "0.5", "0", "0"], ["0", "0", "1", "0"]]
    A = [[payload(marker, w) for w in row] for row in values]
    attack = RK_SOLUTION + textwrap.dedent(f"""

        def rk4_tableau():
            return {A!r}, {[payload(marker, w) for w in ("1/6", "1/3", "1/3", "1/6")]!r}, \\
                {[payload(marker, w) for w in ("0", "0.5", "0.5", "1")]!r}
    """)
    student = submit(tmp_path / "mallory", "04_rk4_tableau", "rk_tableau.py", attack)
    (result,) = grade([student], source=SOURCE, jobs=1, only=["04_rk4_tableau"])
    assert not marker.exists(), "the runner executed the student's text"
    tests = {t.test: t for t in result.exercises[0].tests}
    tableau = {k for k in tests if "rk4_tableau" in k}
    assert tableau == {"test_hidden.py::test_student_rk4_tableau_drives_the_library",
                       "test_public.py::test_rk4_tableau_reproduces_the_stages_of_the_course"}
    assert all(not tests[k].passed for k in tableau)
    assert all(t.passed for k, t in tests.items() if k not in tableau), \
        {k: t.reason for k, t in tests.items() if not t.passed}
    public = tests["test_public.py::test_rk4_tableau_reproduces_the_stages_of_the_course"]
    assert public.reason.startswith("A: expected a numpy array"), public.reason


# -- a payload in every place student data enters ----------------------------------------------

#: what the functions of the submission answer, call after call in turn (one student per group)
KINDS = {
    "texts": ["return P",
              "return ([[P] * 4] * 4, [P] * 4, [P] * 4)",
              "return (P, P)",
              "return {P: [P, {P: (P,)}], 'x': P}"],
    "raises": ["raise RuntimeError(P)",
               "raise type(P[:40], (Exception,), {})(P)",
               "return (['1e10000000'] * 4, '9' * 4000, ['1e-99999999'] * 3)"],
    "sizes": ["return (10 ** 5000, 2 ** 70, -(2 ** 64))",
              "return functools.reduce(lambda acc, _: [acc, P], range(30), P)",
              "return np.zeros(1_000_000)",
              "return np.zeros(5_000_000)"],
}


def payload_module(marker: Path, group: str) -> str:
    answers = "\n".join(f"    if k == {i}:\n        {line}" for i, line in enumerate(KINDS[group]))
    return textwrap.dedent(f"""
        import functools
        import itertools
        import numpy as np
        P = {payload(marker)!r}
        _calls = itertools.count()

        def _answer():
            k = next(_calls) % {len(KINDS[group])}
        {{answers}}

        def __getattr__(name):   # every function the tests ask for
            if name.startswith("__"):
                raise AttributeError(name)
            return lambda *args, **kwargs: _answer()
    """).replace("{answers}", answers)


@pytest.mark.slow
def test_payload_in_every_answer_of_every_exercise_is_inert(tmp_path):
    marker = tmp_path / "ran"
    exercises = find_exercises(SOURCE)
    klass = tmp_path / "class"
    for group in KINDS:
        for ex in exercises:
            submit(klass / group, ex.name, ex.module, payload_module(marker, group))
    results = grade([klass], source=SOURCE, jobs=2, timeout=10.0)
    assert not marker.exists(), "the runner executed a student's text"
    assert sorted(r.student for r in results) == sorted(KINDS)
    for r in results:
        assert len(r.exercises) == 12
        for ex in r.exercises:
            assert not ex.errors, (r.student, ex.name, ex.errors)   # every test ran and failed cleanly
            for t in ex.tests:
                assert not t.passed and t.points == 0, (r.student, ex.name, t.test)
                assert "Traceback" not in t.reason and "\n" not in t.reason


def test_answers_become_numbers_without_reading_text():
    from mslab.grading.checks import as_count, as_numbers

    assert as_numbers([[1, 2], (3, 4.5)], (2, 2)).tolist() == [[1.0, 2.0], [3.0, 4.5]]
    assert as_count(np.float64(3.0)) == 3
    for value in ("0.5", ["0.5"], np.array(["1"]), [True], {"a": 1}, [[1], [1, 2]], np.array([1j])):
        with pytest.raises(AssertionError, match="expected numbers|ragged"):
            as_numbers(value)
    for value in ("7", 7.5, float("inf"), True, [7]):
        with pytest.raises(AssertionError, match="whole number"):
            as_count(value)
