"""Session set-up of the test suite: the Agg backend, and the order in which files are handed out.

``make test`` runs ``tests/`` and the lessons under nbval in one ``pytest -n 3 --dist loadfile
--no-loadscope-reorder`` session: xdist gives each worker a whole file at a time, in collection
order. Collected in alphabetical order, the longest files (the browser test, the compiled fast
path) would start last and end alone on one worker while the others idle. ``LONGEST_FIRST`` puts
them first (longest processing time first); every other file keeps its place after them. This
changes only the order of files, never the order of the tests in a file (nbval's cells run top to
bottom) and never what runs: a file missing from the list, or a list out of date, costs wall time,
never a result.
"""

from __future__ import annotations

import matplotlib
import pytest

matplotlib.use("Agg")

#: the files over about 10 s, longest first (each file's share of a ``pytest -n 2 tests`` run,
#: measured with ``--durations``, 2026-11-28: the hostile class 192 s, the trivial answers 67 s,
#: the payloads 58 s); the lessons by their CPU time (tools/lesson_times.py), but 05 next to 06
#: and 10, whose Run All in tests/test_lab.py it follows; the lessons ahead of the short test
#: files, so that the session ends on files of a few seconds; re-measure when a file grows
LONGEST_FIRST = (
    "tests/test_grading_hostile_class.py",
    "tests/test_fast.py",
    "tests/test_lab.py",
    "tests/test_grading_trivial.py",
    "tests/test_grading_payloads.py",
    "tests/test_precision.py",
    "tests/test_integrators.py",
    "tests/test_session.py",
    "tests/test_grading.py",
    "lessons/06_energy_drift.ipynb",
    "lessons/10_your_own_integrator.ipynb",
    "lessons/05_dahlquist_stability.ipynb",
    "lessons/07_work_precision.ipynb",
    "lessons/03_verlet_leapfrog.ipynb",
    "lessons/09_topology_and_volume.ipynb",
    "lessons/04_implicit_euler.ipynb",
    "lessons/01_euler_taylor.ipynb",
    "lessons/00_mass_spring_systems.ipynb",
    "lessons/02_heun_midpoint_rk4.ipynb",
    "tests/test_stability.py",
    "tests/test_site.py",
    "tests/test_registration.py",
    "tests/test_cli.py",
    "tests/test_effects.py",
    "tests/test_lessons_check.py",
    "tests/test_implicit_cloth.py",
    "tests/test_grading_trust.py",
    "tests/hard_cases/test_stiff.py",
    "tests/test_grading_cli.py",
    "tests/test_wind.py",
    "tests/hard_cases/test_ledger_order.py",
    "tests/test_derive.py",
    "tests/test_cli_newcomer.py",
    "tests/test_extending.py",
    "tests/test_simulate.py",
    "tests/test_scenes.py",
)


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Stable sort of the collected items by their file's place in ``LONGEST_FIRST``."""
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}

    def place(item: pytest.Item) -> int:
        path = item.nodeid.split("::", 1)[0]
        return rank.get(path, len(rank))

    items.sort(key=place)     # sort is stable: the tests of one file keep their order
