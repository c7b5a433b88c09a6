"""The entry point of the platform packages (``mslab release --gradescope/--prairielearn``).

``python -m mslab.commands.platform_entry FORMAT SUBMISSION SOURCE OUTPUT ...`` grades one
submission with ``mslab grade`` and always leaves a ``results.json``: the platform's workers run
it from ``run_autograder`` (Gradescope) or ``run.sh`` (PrairieLearn), see
:mod:`mslab.grading.packages`. It lives with the commands because it calls the command line.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
from pathlib import Path

from mslab.grading.platforms import write_json


def _lock(folder: Path) -> None:
    """Make a folder tree root's only: folders 700, files 600 (the grader itself reads it)."""
    for dirpath, _, filenames in os.walk(folder):
        os.chmod(dirpath, 0o700)
        for name in filenames:
            path = os.path.join(dirpath, name)
            if not os.path.islink(path):
                os.chmod(path, 0o600)


def _not_graded(fmt: str, why: str) -> dict:
    """Return the results document of a submission the grader refused (one line saying why)."""
    if fmt == "prairielearn":
        return {"gradable": False, "format_errors": [why], "score": 0.0, "tests": []}
    return {"score": 0.0, "output": f"Not graded: {why}", "tests": []}


def entry(argv: list[str] | None = None) -> int:
    """Grade one submission into a platform's ``results.json``; return 0 once it is written.

    Arguments: ``FORMAT SUBMISSION SOURCE OUTPUT [--isolation MODE] [--exercise NAME]... [NAME]...``.
    A submission the grader refuses (exit 2: say, no file) still gets a ``results.json``
    saying why, so that the student sees a reason rather than a failed autograder.
    """
    from mslab.cli import main as cli_main

    p = argparse.ArgumentParser(prog="python -m mslab.commands.platform_entry")
    p.add_argument("format", choices=("gradescope", "prairielearn"))
    p.add_argument("submission")
    p.add_argument("source")
    p.add_argument("output")
    p.add_argument("--isolation", default="rlimits")
    p.add_argument("--exercise", action="append", default=[])
    p.add_argument("names", nargs="*")
    args = p.parse_intermixed_args(argv)
    _lock(Path(args.source))
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    # the platform's upload folder is one submission, whatever else the student uploaded beside it
    cmd = ["grade", args.submission, "--source", args.source, "--isolation", args.isolation,
           "--format", args.format, "--output", args.output, "--layout", "submission"]
    for name in [*args.exercise, *args.names]:
        cmd += ["--exercise", name]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli_main(cmd)
    # the platforms keep stdout and stderr (for the instructor, maybe shown to the student):
    # the per-test report names hidden tests, so only the totals and the warnings go there
    print("\n".join(line for line in out.getvalue().splitlines()
                    if line.lstrip().startswith(("total:", "isolation:", "resources:"))))
    sys.stderr.write(err.getvalue())
    if code != 0:
        lines = [line for line in err.getvalue().splitlines() if line.startswith("mslab: error:")]
        why = lines[-1].removeprefix("mslab: error: ") if lines else f"the grader stopped (exit code {code})"
        write_json(args.output, _not_graded(args.format, why[:300]))
    return 0


if __name__ == "__main__":
    sys.exit(entry())
