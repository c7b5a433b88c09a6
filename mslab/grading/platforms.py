"""Grades where courses keep them: Gradescope, PrairieLearn and Canvas files from graded submissions.

``mslab grade --format FMT --output FILE`` writes one of:

``gradescope``
    the autograder's ``results.json`` of one submission, as Gradescope's autograder
    specification defines it (https://gradescope-autograders.readthedocs.io/en/latest/specs/,
    "Output format"; source: github.com/gradescope/autograder_samples, ``docs/specs.md``):
    top level ``score`` (overrides the tests' total), optional ``execution_time``,
    ``output``, ``visibility``, ``stdout_visibility``, ``extra_data`` and ``tests``; each
    test optional ``score``, ``max_score``, ``status`` (``passed``/``failed``), ``name``,
    ``number``, ``output``, ``tags``, ``visibility``, ``extra_data``; visibilities
    ``hidden``, ``after_due_date``, ``after_published``, ``visible``.
``prairielearn``
    the external grader's ``results.json`` of one submission, as PrairieLearn's
    "External Grading" page defines it (https://prairielearn.readthedocs.io/en/latest/externalGrading/,
    "Grading results"; source: github.com/PrairieLearn/PrairieLearn, ``docs/externalGrading.md``):
    ``score`` in [0, 1] (required when gradable), ``gradable`` (false: no points won or
    lost, no attempt used; ``format_errors`` say why), ``message``, ``output`` and
    ``tests`` with ``name``, ``description``, ``points``, ``max_points``, ``message``,
    ``output``; at most 1 MB.
``canvas``
    a gradebook CSV for Canvas's Grades > Import, laid out as Canvas exports it (columns
    ``Student``, ``ID``, ``SIS User ID``, ``SIS Login ID``, ``Section``, then one
    assignment column ``Name (id)``; a new name without an id makes Canvas create the
    assignment): see "Import CSV File for Carmen Grades",
    https://teaching.resources.osu.edu/toolsets/carmencanvas/guides/calculating-final-grades/import-csv-file-carmen-grades
    and Canvas's own export. A second row ``Points Possible`` gives the assignment's
    maximum, as in Canvas's export.
``csv``
    mslab's own gradebook (:func:`mslab.grading.report.gradebook_rows`).

What students see. Both platforms show a test's name and output to the student, so a
hidden test appears as ``NN_topic: hidden test k`` with its points and the grader's fixed
phrase (``hidden test: wrong value``), never its function name, source or message. On
Gradescope the hidden tests are ``after_published``: a student sees them, and the total,
once the instructor publishes the grades (the specification keeps ``hidden`` for tests
that carry no points, and hides the total while any test is not visible); public tests
are ``visible``. PrairieLearn shows every test at once, so only the anonymised form ever
reaches it. The Canvas file holds totals only.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mslab.files import atomic_write
from mslab.grading.layout import HIDDEN
from mslab.grading.remote import PHRASES
from mslab.grading.report import csv_cell, gradebook_rows, printable, write_csv

if TYPE_CHECKING:
    from mslab.grading.autograde import SubmissionResult

#: the formats ``mslab grade --format`` writes
FORMATS = ("csv", "gradescope", "prairielearn", "canvas")
#: formats holding one submission (a platform grades each submission on its own)
SINGLE = ("gradescope", "prairielearn")
#: Canvas's identity columns, in the order of its export
CANVAS_COLUMNS = ("Student", "ID", "SIS User ID", "SIS Login ID", "Section")
CANVAS_POINTS_ROW = "Points Possible"
#: the assignment column when none is named (Canvas creates the assignment on import)
CANVAS_ASSIGNMENT = "mslab exercises"
#: Gradescope visibility of a hidden test and of a public one
HIDDEN_VISIBILITY, PUBLIC_VISIBILITY = "after_published", "visible"
#: PrairieLearn refuses results larger than this (bytes)
PRAIRIELEARN_MAX_BYTES = 1_000_000
#: characters of one test's message kept
MESSAGE_CHARS = 500


def is_hidden(test: str) -> bool:
    """Tell whether a test id ``file::name`` belongs to a hidden test file."""
    return bool(HIDDEN.match(test.split("::")[0]))


def student_tests(result: SubmissionResult) -> list[dict[str, Any]]:
    """Return every test of a submission as a student may see it.

    Each entry: ``name``, ``points``, ``max_points``, ``passed``, ``message`` and
    ``hidden``. A public test keeps its name (``NN_topic: test_x``) and its reason; a
    hidden one is numbered within its exercise (``NN_topic: hidden test 2``) and carries
    only the grader's fixed phrase (the reason of :func:`mslab.grading.autograde._score`,
    which is already that phrase), or "passed".
    """
    out = []
    for ex in result.exercises:
        k = 0
        for t in ex.tests:
            hidden = is_hidden(t.test)
            if hidden:
                k += 1
                name = f"{ex.name}: hidden test {k}"
                message = "passed" if t.passed else _hidden_phrase(t.reason)
            else:
                name = f"{ex.name}: {t.test.split('::')[-1]}"
                message = "passed" if t.passed else printable(t.reason, MESSAGE_CHARS)
            out.append({"name": name, "points": float(t.points), "max_points": float(t.max_points),
                        "passed": bool(t.passed), "message": message, "hidden": hidden})
    return out


def _hidden_phrase(reason: str) -> str:
    """Return the fixed phrase of a failed hidden test (a generic one if the reason is anything else)."""
    allowed = {f"hidden test: {p}" for p in PHRASES.values()}
    return reason if reason in allowed else "hidden test: not passed"


def _summary(result: SubmissionResult) -> str:
    """Return one line per exercise (points) and the reasons that kept an exercise from being graded."""
    lines = []
    for ex in result.exercises:
        lines.append(f"{ex.name}: {ex.total:g}/{ex.max_points:g}")
        lines.extend(f"  {printable(e, 300)}" for e in ex.errors[:3])
    lines.append(f"total: {result.total:g}/{result.max_points:g}")
    return "\n".join(lines)


def gradescope_results(result: SubmissionResult) -> dict[str, Any]:
    """Return Gradescope's ``results.json`` document for one graded submission."""
    tests = []
    for number, t in enumerate(student_tests(result), start=1):
        tests.append({"name": t["name"], "number": str(number), "score": t["points"],
                      "max_score": t["max_points"], "status": "passed" if t["passed"] else "failed",
                      "output": t["message"],
                      "visibility": HIDDEN_VISIBILITY if t["hidden"] else PUBLIC_VISIBILITY,
                      "tags": ["hidden" if t["hidden"] else "public"]})
    return {"score": result.total, "output": _summary(result), "stdout_visibility": "hidden",
            "extra_data": {"isolation": result.isolation, "resources": result.resources},
            "tests": tests}


def prairielearn_results(result: SubmissionResult) -> dict[str, Any]:
    """Return PrairieLearn's external-grader ``results.json`` document for one graded submission.

    ``score`` is the fraction of the points earned. A submission none of whose exercises
    could be graded at all (its file missing, refused, or the runner never answered) is
    ``gradable: false`` with the reasons in ``format_errors``: the student loses no attempt.
    """
    tests = [{"name": t["name"], "description": "hidden test" if t["hidden"] else "public test",
              "points": t["points"], "max_points": t["max_points"], "message": t["message"]}
             for t in student_tests(result)]
    maximum = result.max_points
    score = result.total / maximum if maximum > 0 else 0.0
    doc: dict[str, Any] = {"gradable": True, "score": min(max(score, 0.0), 1.0),
                           "message": f"{result.total:g}/{maximum:g} points", "output": _summary(result),
                           "tests": tests}
    if result.exercises and all(ex.errors for ex in result.exercises):
        doc["gradable"] = False
        doc["format_errors"] = [printable(f"{ex.name}: {ex.errors[0]}", 300) for ex in result.exercises]
    return doc


def canvas_rows(results: Sequence[SubmissionResult], assignment: str | None = None,
                id_column: str = "SIS Login ID") -> list[list[str]]:
    """Return a Canvas gradebook import: header, ``Points Possible``, one row per student.

    The student's row name (:func:`mslab.grading.intake.unique_names`) goes into ``Student``
    and into ``id_column`` (one of Canvas's identity columns, by default ``SIS Login ID``: name
    the folders by it; never formula-escaped, :func:`login_cell`); the
    total goes into the one ``assignment`` column (``"Title (canvas id)"`` to update an
    existing assignment; a title alone makes Canvas create one).
    """
    if id_column not in CANVAS_COLUMNS[1:4]:
        raise ValueError(f"id_column: one of {', '.join(CANVAS_COLUMNS[1:4])}, not {id_column!r}")
    title = _canvas_title(assignment)
    column = CANVAS_COLUMNS.index(id_column)
    maximum = max((r.max_points for r in results), default=0.0)
    rows = [[*CANVAS_COLUMNS, csv_cell(title)], [CANVAS_POINTS_ROW, "", "", "", "", f"{maximum:g}"]]
    for r in results:
        row = [csv_cell(r.student), "", "", "", "", f"{r.total:g}"]
        row[column] = login_cell(r.student)
        rows.append(row)
    return rows


def login_cell(name: str) -> str:
    """Return the identity cell of a Canvas row: the name as it is, or empty if a spreadsheet would run it.

    Escaping (``'-dash``) would make a login that is no one's, so a name starting with one
    of ``= + - @`` (or holding an escaped character) leaves the cell empty: Canvas's import
    preview then lists the row as unmatched instead of matching someone else.
    """
    return name if name == csv_cell(name) and "\\" not in name else ""


def check_format(fmt: str, output: str | None, n_paths: int, assignment: str | None) -> None:
    """Check ``mslab grade``'s format options before anything is graded (ValueError naming the option)."""
    if fmt not in FORMATS:
        raise ValueError(f"--format: one of {', '.join(FORMATS)}, not {fmt!r}")
    if fmt != "csv" and not output:
        raise ValueError(f"--format: {fmt} needs --output FILE")
    if fmt in SINGLE and n_paths != 1:
        raise ValueError(f"--format: {fmt} writes the results.json of one submission, not of {n_paths}")
    if assignment is not None and fmt != "canvas":
        raise ValueError("--assignment: only for --format canvas")
    if fmt == "canvas":
        _canvas_title(assignment)


def _canvas_title(assignment: str | None) -> str:
    title = (assignment or CANVAS_ASSIGNMENT).strip()
    if not title or len(title) > 255 or not title.isprintable():
        raise ValueError(f"--assignment: a one-line title, not {assignment!r}")
    return title


def write_json(path: str | Path, doc: dict[str, Any], limit: int | None = None) -> Path:
    """Write ``doc`` as JSON atomically; past ``limit`` bytes, test messages and output are shortened."""
    text = json.dumps(doc, indent=2, allow_nan=False) + "\n"
    if limit is not None and len(text.encode()) > limit:
        for t in doc.get("tests", []):  # shorten the messages, never the scores
            t["message"] = t["message"][:80]
        doc["output"] = doc.get("output", "")[:2000]
        text = json.dumps(doc, indent=2, allow_nan=False) + "\n"

    def write(tmp: str) -> None:
        Path(tmp).write_text(text)

    return atomic_write(path, write)


def write_grades(path: str | Path, fmt: str, results: Sequence[SubmissionResult],
                 assignment: str | None = None) -> Path:
    """Write graded ``results`` to ``path`` in the format ``fmt`` (one of :data:`FORMATS`), atomically.

    ``gradescope`` and ``prairielearn`` hold one submission (ValueError for more);
    ``assignment`` names the Canvas column.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format: one of {', '.join(FORMATS)}, not {fmt!r}")
    if fmt in SINGLE and len(results) != 1:
        raise ValueError(f"format: {fmt} writes one submission's results.json; "
                         f"{len(results)} submissions were graded")
    if fmt == "gradescope":
        return write_json(path, gradescope_results(results[0]))
    if fmt == "prairielearn":
        return write_json(path, prairielearn_results(results[0]), limit=PRAIRIELEARN_MAX_BYTES)
    rows = canvas_rows(results, assignment) if fmt == "canvas" else gradebook_rows(results)
    return write_csv(path, rows)


def read_canvas(path: str | Path) -> tuple[str, float, dict[str, float]]:
    """Read a Canvas gradebook written by :func:`canvas_rows`: (assignment, points possible, scores).

    ``scores`` maps the ``Student`` cell to the assignment's score.
    """
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    if len(rows) < 2 or tuple(rows[0][:5]) != CANVAS_COLUMNS or len(rows[0]) != 6:
        raise ValueError(f"{path}: not a Canvas gradebook of one assignment")
    if rows[1][0].strip() != CANVAS_POINTS_ROW:
        raise ValueError(f"{path}: no '{CANVAS_POINTS_ROW}' row")
    possible = float(rows[1][5])
    scores = {row[0]: float(row[5]) for row in rows[2:]}
    if not all(math.isfinite(v) for v in (possible, *scores.values())):
        raise ValueError(f"{path}: a score is not a finite number")
    return rows[0][5], possible, scores
