"""A test's CPU limit counts all the calls of its sandbox together, quick calls too.

The runner measures the sandbox's CPU time (a cgroup file, or without a cgroup a walk of
``/proc``) only when a poll interval has passed since the last measurement
(:meth:`mslab.grading.box.Budget.exceeded`): a test of many quick calls then pays no
measurement per call. Here a student burns a fixed CPU time per call, many quick calls in a
row: the limit must stop them within a poll interval of CPU after it is used up, and not
before (each measured, not assumed), in the isolation this machine grades with and in the
one without a cgroup (``rlimits`` as an unprivileged user measures through ``/proc``).
"""

from __future__ import annotations

import os

import pytest

from mslab.grading import isolation
from mslab.grading.box import POLL_CGROUP, POLL_PROC
from mslab.grading.remote import Sandbox, Student, StudentError

BURNER = '''
import time

def burn(seconds):
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass
    return seconds
'''
#: the test's CPU limit and each call's CPU time (seconds); the calls are short beside a poll
LIMIT, PER_CALL = 0.6, 0.03


@pytest.mark.parametrize("cgroup", [True, False], ids=["as-graded", "no-cgroup"])
def test_many_quick_calls_end_on_the_cpu_limit(tmp_path, cgroup):
    from mslab.grading import box

    mode = isolation.detect("auto")
    cgroups, why = box.setup(1, f"mslab-grade-budget-{os.getpid()}") if cgroup else (None, "")
    if cgroup and not cgroups:
        pytest.skip(f"no cgroup to grade with on this machine ({why}); the no-cgroup case measures /proc")
    module = tmp_path / "burner.py"
    module.write_text(BURNER)
    sandbox = Sandbox(module, tmp_path, mode=mode, cgroups=cgroups)
    try:
        student = Student(sandbox, LIMIT)
        burn = student.burn
        done = 0
        with pytest.raises(StudentError) as stop:
            for _ in range(200):  # 6 s of CPU: far beyond the limit
                burn(PER_CALL)
                done += 1
    finally:
        sandbox.close()
        if cgroups:
            box.teardown(cgroups)
    assert stop.value.kind == "cpu", str(stop.value)
    every = POLL_CGROUP if cgroups else POLL_PROC
    # used up after LIMIT / PER_CALL calls (a little sooner: the sandbox's own work counts
    # too); found within one poll interval of wall time, which holds at most
    # every / PER_CALL more calls (fewer on a busy machine), plus /proc's 10 ms ticks
    assert LIMIT / PER_CALL - 2 <= done <= (LIMIT + every + 0.02) / PER_CALL + 1, done
