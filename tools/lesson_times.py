"""Print the CPU time each lesson takes to run top to bottom, cold.

Usage (from the repository root)::

    .venv/bin/python tools/lesson_times.py                          # every lessons/NN_*.ipynb
    .venv/bin/python tools/lesson_times.py lessons/03_verlet_leapfrog.ipynb --warm

Each notebook runs in a fresh ``python3`` kernel (the notebook file is not changed) inside a child
process; its CPU time is that child's and its kernel's user + system time, from
``resource.getrusage(RUSAGE_CHILDREN)``, so other work on the machine does not count. *Cold*
(the default) gives the run empty numba and mslab caches (``NUMBA_CACHE_DIR``,
``MSLAB_CACHE_DIR`` set to a fresh temporary folder), as on a student's first run; ``--warm``
keeps the caches. The wall time is printed beside it. Exit 1 when a lesson exceeds ``--limit``
seconds of CPU (default 60), 2 when one fails to run.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LESSONS = ROOT / "lessons"
RUN_ONE = """
import sys, nbformat
from nbclient import NotebookClient
nb = nbformat.read(sys.argv[1], as_version=4)
NotebookClient(nb, timeout=600, kernel_name="python3", allow_errors=False,
               resources={"metadata": {"path": sys.argv[2]}}).execute()
"""


def cpu_seconds(path: Path, cold: bool = True) -> tuple[float, float]:
    """(CPU seconds, wall seconds) of one run of the notebook at ``path``; raises on a failed run."""
    env = dict(os.environ)
    with tempfile.TemporaryDirectory(prefix="lesson-times-") as cache:
        if cold:
            env.update(NUMBA_CACHE_DIR=cache, MSLAB_CACHE_DIR=cache)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", RUN_ONE, str(path), str(path.parent)], env=env,
                              capture_output=True, text=True, check=False)
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("notebooks", nargs="*", type=Path, help="default: every lessons/NN_*.ipynb")
    parser.add_argument("--warm", action="store_true", help="keep numba's and mslab's caches")
    parser.add_argument("--limit", type=float, default=60.0, help="CPU seconds allowed per lesson")
    args = parser.parse_args(argv)
    paths = args.notebooks or sorted(LESSONS.glob("[0-9][0-9]*_*.ipynb"))
    over = 0
    for path in paths:
        try:
            cpu, wall = cpu_seconds(path.resolve(), cold=not args.warm)
        except RuntimeError as exc:
            print(f"lesson_times: error: {path}: {exc}", file=sys.stderr)
            return 2
        flag = "  OVER" if cpu > args.limit else ""
        over += bool(flag)
        kind = "warm" if args.warm else "cold"
        print(f"{path.name:40s} CPU {cpu:6.1f} s   wall {wall:6.1f} s   ({kind}){flag}", flush=True)
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
