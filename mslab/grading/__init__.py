"""Graded exercises: the student release and the autograder (see exercises/README.md)."""

from mslab.grading.autograde import SubmissionResult, format_report, grade, gradebook_rows
from mslab.grading.layout import Exercise, find_exercises
from mslab.grading.release import release, solution_lines, strip_solutions

__all__ = ["Exercise", "SubmissionResult", "find_exercises", "format_report", "grade", "gradebook_rows",
           "release", "solution_lines", "strip_solutions"]
