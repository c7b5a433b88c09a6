"""Grading time of a class of 30: quiet, and with one CPU hog among them (issue 20).

Usage: ``python benchmarks/grading_hog.py [--repeats 3] [--exercise 07_stability_function]``;
writes ``benchmarks/grading_hog.json``. Nothing here is a test.
Every student has the reference solution of the exercise; in the second class one of the
30 instead forks 40 busy loops (each ``setsid``) at import and sleeps in every call. The
runs alternate quiet/hog; the figure is the median of each, and their ratio. Prints one
JSON document (machine, load, isolation and cgroup, times, ratio, marks, hog loops left).
The load average before each run is recorded too; during and just after a hog run it
includes the hog's own 40 loops (about +40), so ``load_before`` (taken before any run) is
the measure of other work on the machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mslab.grading import find_exercises, grade  # noqa: E402

HOG = '''
import subprocess, sys
for _ in range(40):
    try:
        subprocess.Popen([sys.executable, "-c", "while True: pass"], start_new_session=True,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        break

def __getattr__(name):
    import time
    def sleeper(*args, **kwargs):
        time.sleep(1000)
    return sleeper
'''


def _loops() -> int:
    """Busy loops of the hog still running (its command line is unique on the machine)."""
    n = 0
    for entry in Path("/proc").iterdir():
        try:
            n += entry.name.isdigit() and b"while True: pass" in (entry / "cmdline").read_bytes()
        except OSError:
            pass
    return n


def make_class(base: Path, exercise: str, hog: bool) -> Path:
    (ex,) = [e for e in find_exercises(ROOT / "exercises") if e.name == exercise]
    cls = base / ("hog" if hog else "quiet")
    for k in range(30):
        folder = cls / f"student{k:02d}" / exercise
        folder.mkdir(parents=True)
        if hog and k == 0:
            (folder / ex.module).write_text(HOG)
        else:
            shutil.copyfile(ex.folder / ex.module, folder / ex.module)
    return cls


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--exercise", default="07_stability_function")
    ap.add_argument("--timeout", type=float, default=10.0)
    args = ap.parse_args()
    base = Path(tempfile.mkdtemp(prefix="mslab-hog-bench-"))
    times = {"quiet": [], "hog": []}
    loads = {"quiet": [], "hog": []}
    marks = {}
    load0 = os.getloadavg()
    leftover = 0
    try:
        classes = {name: make_class(base, args.exercise, name == "hog") for name in times}
        for _ in range(args.repeats):
            for name, cls in classes.items():
                loads[name].append(round(os.getloadavg()[0], 2))
                t0 = time.perf_counter()
                results = grade([cls], source=ROOT / "exercises", jobs=2, timeout=args.timeout,
                                only=[args.exercise])
                times[name].append(time.perf_counter() - t0)
                print(f"{name}: {times[name][-1]:.1f} s (load {os.getloadavg()[0]:.1f})", file=sys.stderr)
                honest = [r for r in results if not (name == "hog" and r.student == "student00")]
                marks[name] = sum(r.total == r.max_points for r in honest), len(honest)
                marks["resources"] = results[0].resources
                marks["isolation"] = results[0].isolation
                leftover = max(leftover, _loops())
    finally:
        shutil.rmtree(base, ignore_errors=True)
    med = {k: statistics.median(v) for k, v in times.items()}
    machine = (f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
               f"{platform.system()} {platform.release()}")
    doc = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "machine": machine,
           "load_before": load0, "load_after": os.getloadavg(), "exercise": args.exercise,
           "timeout": args.timeout, "jobs": 2, "isolation": marks.pop("isolation"),
           "resources": marks.pop("resources"), "times_s": times, "load_before_each_run": loads,
           "median_s": med, "ratio_hog_over_quiet": med["hog"] / med["quiet"],
           "honest_full_marks": marks, "hog_loops_left_after_grading": leftover}
    text = json.dumps(doc, indent=1) + "\n"
    (ROOT / "benchmarks" / "grading_hog.json").write_text(text)
    print(text, end="")


if __name__ == "__main__":
    main()
