"""Grading v3 (issue 20): nothing the sandbox says is trusted; one student cannot touch another.

1. A class of 30 graded together, in each isolation mode: five leakers, one CPU hog and
   24 honest students (the reference solution and honest variations of it).

   - Leakers send a hidden test's inputs back in the sandbox's words (an exception class
     named ``<wire>``, a class name or an exit code carrying the data). A unique marker
     planted in a hidden test's inputs must appear nowhere in the reports, the JSON, the
     CSV or the journal; the same marker in a public test *does* reach its report (so the
     leakers do send it, and this test can fail).
   - The hog forks busy loops, each with ``setsid``, at import: its tests hit the CPU
     limit of its sandbox (so its loops ran), every honest classmate keeps full marks, and
     nothing (loop, temporary folder, cgroup) outlives the grading.
2. A CPU hog in a grading of its own beside an honest classmate's: the classmate keeps full
   marks; the hog's loops and cgroups end with its grader (stopped by SIGTERM).
3. Grading as an unprivileged user (a user created for the test, when run as root).

Each grading runs exercise 07 only; the runs are bounded (``timeout``) and synchronise on
processes seen in /proc, never on sleeps."""

from __future__ import annotations

import contextlib
import json
import os
import pwd
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

import mslab.grading.autograde as autograde_module
from mslab.grading import grade
from mslab.grading.box import PREFIX
from mslab.grading.box import _mounts as cgroup_mounts
from mslab.grading.box import _own as own_cgroup
from mslab.grading.isolation import _probe
from mslab.grading.report import format_report, gradebook_rows

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
TARGET, MODULE = "07_stability_function", "stability_function.py"
HIDDEN_MARK, PUBLIC_MARK = "4271953", "3859137"
#: CPU seconds per test in the class of 30: the hog's cost is about its number of tests times
#: this; the reference and its variations pass every test with 0.03 s (measured): a 16x margin
CLASS_TIMEOUT = 0.5
#: busy loops of the hog in the class (4x the cores of a 2-core machine; each restart of its
#: sandbox forks them again, so more only slows its own grading)
CLASS_HOG_LOOPS = 8
#: marks in the command lines of the hogs' loops (the class's, the separate grading's)
CLASS_HOG_MARK, HOG_MARK = "mslab-class-hog-loop", "mslab-hog-loop"
MODES = [m for m in ("bwrap", "namespaces") if sys.platform.startswith("linux") and _probe(m)]

MARKED_TEST = """

@pytest.mark.points(1)
def test_marked_inputs_{kind}(student):
    A = np.array([[0.0, 0.0], [0.{mark}, 0.0]])
    b = np.array([0.5, 0.5])
    z = np.array([-0.{mark} + 0.{mark}j, -1.0])
    R = 1.0 + z * (b[0] + b[1]) + z * z * b[1] * A[1, 0]
    check_array(student.stability_function(A, b, z), R, rtol=1e-10, atol=1e-12, what="R(z)")
"""

#: every leaker sends its arguments back in a way the old grader quoted
LEAKERS = {
    "wire_class": """
        import numpy as np
        def stability_function(A, b, z):
            raise type("<wire>", (Exception,), {})(repr(np.asarray(A).tolist()))
        def real_stability_interval(A, b, tol=1e-12):
            raise type("<wire>", (Exception,), {})(repr(np.asarray(A).tolist()))
    """,
    "class_name": """
        import re
        import numpy as np
        def _leak(A):
            return type("leak_" + re.sub(r"\\W", "_", repr(np.asarray(A).tolist())), (), {})()
        def stability_function(A, b, z):
            return _leak(A)
        def real_stability_interval(A, b, tol=1e-12):
            return _leak(A)
    """,
    "exception_name": """
        import re
        import numpy as np
        def _leak(A):
            return type("L_" + re.sub(r"\\W", "_", repr(np.asarray(A).tolist())), (ValueError,), {})()
        def stability_function(A, b, z):
            raise _leak(A)
        def real_stability_interval(A, b, tol=1e-12):
            raise _leak(A)
    """,
    "exit_message": """
        import sys
        import numpy as np
        def stability_function(A, b, z):
            sys.exit(repr(np.asarray(A).tolist()))
        def real_stability_interval(A, b, tol=1e-12):
            sys.exit(repr(np.asarray(A).tolist()))
    """,
    "exit_code": """
        import os
        import numpy as np
        def stability_function(A, b, z):
            os._exit(int(round(np.asarray(A)[-1, 0] * 100)) % 256)
        def real_stability_interval(A, b, tol=1e-12):
            os._exit(7)
    """,
}


#: a CPU hog: busy loops, each in its own session, forked at import; every call sleeps
HOG = """
import subprocess, sys
for _ in range(LOOPS):
    try:
        subprocess.Popen([sys.executable, "-c", "# MARK\\nwhile True: pass"],
                         start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        break

def stability_function(A, b, z):
    import time
    time.sleep(1000)

def real_stability_interval(A, b, tol=1e-12):
    import time
    time.sleep(1000)
"""


def _hog_loops(mark: str = HOG_MARK) -> int:
    """Busy loops of a hog running now (found by the mark in their command line)."""
    n = 0
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                n += mark.encode() in (entry / "cmdline").read_bytes()
            except OSError:
                pass
    return n


def _wait_for(condition, limit: float, what: str) -> None:
    end = time.monotonic() + limit
    while not condition():
        if time.monotonic() > end:
            raise AssertionError(f"{what} within {limit:g} s")
        time.sleep(0.05)


def _source_with_markers(base: Path) -> Path:
    """A copy of exercise 07 whose public and hidden tests call with marked inputs."""
    src = base / "source"
    shutil.copytree(SOURCE / TARGET, src / TARGET, ignore=shutil.ignore_patterns("__pycache__"))
    for name, kind, mark in (
        ("test_hidden.py", "hidden", HIDDEN_MARK),
        ("test_public.py", "public", PUBLIC_MARK),
    ):
        path = src / TARGET / name
        text = path.read_text()
        if "check_array" not in text.split("def ")[0]:
            text = text.replace(
                "import pytest\n", "import pytest\n\nfrom mslab.grading.checks import check_array\n", 1
            )
        path.write_text(text + MARKED_TEST.format(kind=kind, mark=mark))
    return src


#: honest variations of the reference solution: (old text, new text) replaced in its file
HONEST_VARIANTS = [
    [],
    [  # every z at once: one batched solve
        ("""    R = np.empty(z.shape, dtype=complex)
    for idx in np.ndindex(*z.shape):
        stages = np.linalg.solve(np.eye(s) - z[idx] * A, np.ones(s))
        R[idx] = 1.0 + z[idx] * (b @ stages)
    return R""",
         """    M = np.eye(s) - z.reshape(-1, 1, 1) * A
    stages = np.linalg.solve(M, np.ones((z.size, s, 1)))[..., 0]
    return (1.0 + z.reshape(-1) * (stages @ b)).reshape(z.shape)"""),
    ],
    [  # the bisection written as a counted loop
        ("""    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if unstable(mid):
            lo = mid
        else:
            hi = mid""",
         """    for _ in range(200):
        if hi - lo <= tol:
            break
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if unstable(mid) else (lo, mid)"""),
    ],
]


def _honest_source(k: int) -> str:
    """Student ``k``'s honest file: the reference, varied, with a comment of its own."""
    text = (SOURCE / TARGET / MODULE).read_text()
    for old, new in HONEST_VARIANTS[k % len(HONEST_VARIANTS)]:
        assert old in text, "the reference solution changed: update HONEST_VARIANTS"
        text = text.replace(old, new)
    return f"# student {k}: my own work\n" + text


@contextlib.contextmanager
def private_tmp(tmp: Path) -> Iterator[list[str]]:
    """Grade with ``tmp`` as the temporary folder (``TMPDIR`` and :mod:`tempfile`); yields the
    names of the grading folders made meanwhile (each also names the grading's cgroups), so
    :func:`leftovers` can look for exactly those, whatever graders run beside the test."""
    names: list[str] = []

    class Spied(autograde_module.Owned):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            names.append(self.name)

    saved, saved_dir = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"] = tempfile.tempdir = str(tmp)
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(autograde_module, "Owned", Spied)
            yield names
    finally:
        tempfile.tempdir = saved_dir
        if saved is None:
            del os.environ["TMPDIR"]
        else:
            os.environ["TMPDIR"] = saved


def leftovers(tmp: Path, names: list[str], mark: str = CLASS_HOG_MARK) -> list[str]:
    """What gradings in the private temporary folder ``tmp`` left behind: processes bearing
    ``mark``, any grading folder (``mslab-grade-*``, ``.mslab-grade-build-*``) in ``tmp``, and
    the cgroups of the gradings named ``names``."""
    left = [f"{n} processes marked {mark}"] if (n := _hog_loops(mark)) else []
    left += [str(p) for p in tmp.glob(f"{PREFIX}*")] + [str(p) for p in tmp.glob(f".{PREFIX}*")]
    v2, v1 = cgroup_mounts()
    hierarchies = {"": v2} if v2 else {}
    hierarchies.update(v1)
    for name, mount in hierarchies.items():
        try:
            base = Path(mount) / own_cgroup(name).lstrip("/")
        except OSError:
            continue
        left += [str(base / n) for grading in names for n in (grading, f"{grading}-grader")
                 if (base / n).exists()]
    return left


def test_leftovers_finds_what_a_grading_leaves(tmp_path):
    """The check can fail: a planted grading folder, build folder and marked process are caught."""
    assert leftovers(tmp_path, [], mark="mslab-planted-mark") == []
    (tmp_path / f"{PREFIX}0123456789abcdef").mkdir()
    (tmp_path / f".{PREFIX}build-x").mkdir()
    # it says "ready" once running (its command line is set), then waits for its stdin to close
    code = "import sys; print('ready', flush=True); sys.stdin.read() # mslab-planted-mark"
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout.readline() == "ready\n"
        left = leftovers(tmp_path, [], mark="mslab-planted-mark")
    finally:
        proc.communicate(timeout=60)
    assert len(left) == 3, left
    assert any("1 processes marked" in x for x in left)


@pytest.fixture(
    scope="module", params=MODES or [pytest.param("none", marks=pytest.mark.skip("no namespaces"))]
)
def graded_class(request, tmp_path_factory):
    """A class of 30 graded together against the marked tests: the leakers, one CPU hog
    and 24 honest students (the reference and honest variations of it)."""
    base = tmp_path_factory.mktemp(f"class-{request.param}")
    src = _source_with_markers(base)
    cls = base / "class"
    sources = {name: textwrap.dedent(code) for name, code in LEAKERS.items()}
    sources["hog"] = HOG.replace("LOOPS", str(CLASS_HOG_LOOPS)).replace("MARK", CLASS_HOG_MARK)
    sources.update({f"honest{k:02d}": _honest_source(k) for k in range(30 - len(sources))})
    for name, text in sources.items():
        (cls / name / TARGET).mkdir(parents=True)
        (cls / name / TARGET / MODULE).write_text(text)
    journal = base / "book.journal"
    (base / "tmp").mkdir()
    with private_tmp(base / "tmp") as names:
        results = grade([cls], source=src, jobs=2, timeout=CLASS_TIMEOUT, isolation=request.param,
                        journal=journal)
    assert names, "no grading folder was made: the leftover check looked for nothing"
    left = leftovers(base / "tmp", names)
    texts = [format_report(r) for r in results]
    texts.append(json.dumps([r.to_dict() for r in results]))
    texts.append("\n".join(",".join(row) for row in gradebook_rows(results)))
    texts.append(journal.read_text())
    return {r.student: r for r in results}, texts, left


def _reasons(result, prefix: str = "test_hidden") -> set[str]:
    return {t.reason for e in result.exercises for t in e.tests if t.test.startswith(prefix)}


def test_a_class_of_30_has_one_hog_five_leakers_and_24_honest(graded_class):
    results = graded_class[0]
    assert len(results) == 30
    assert sum(name.startswith("honest") for name in results) == 24


def test_every_honest_student_has_full_marks(graded_class):
    for name, r in graded_class[0].items():
        if name.startswith("honest"):
            assert r.total == r.max_points > 0, (name, [(t.test, t.reason) for e in r.exercises
                                                        for t in e.tests if not t.passed])


def test_the_hog_hogged_and_scores_nothing(graded_class):
    """Its hidden tests time out, on the CPU limit of its sandbox: its loops ran, in its box.

    (On a machine so busy that the hog's box gets under a twentieth of a core, a test may
    reach the wall-clock backstop first; at least one reaches the CPU limit.)
    """
    hog = graded_class[0]["hog"]
    assert hog.total == 0
    reasons = _reasons(hog)
    assert reasons <= {"hidden test: timed out (CPU time limit)", "hidden test: timed out (wall-clock limit)"}
    assert "hidden test: timed out (CPU time limit)" in reasons


def test_nothing_outlives_grading(graded_class):
    assert graded_class[2] == []


def test_the_leakers_do_send_the_public_marker(graded_class):
    """The channel is real: in a public test the student's own message (bounded) is shown."""
    results = graded_class[0]
    for name in ("wire_class", "class_name", "exception_name", "exit_message"):
        (marked,) = [
            t for e in results[name].exercises for t in e.tests if t.test.endswith("marked_inputs_public")
        ]
        assert PUBLIC_MARK in marked.reason, (name, marked.reason)
    (code,) = [t for e in results["exit_code"].exercises for t in e.tests if t.test.endswith("inputs_public")]
    assert "exited with code 39" in code.reason  # round(0.3859137 * 100): the runner saw the status


def test_the_hidden_marker_appears_nowhere(graded_class):
    results, texts, _ = graded_class
    for text in texts:
        assert HIDDEN_MARK not in text
    for name in LEAKERS:
        assert results[name].total == 0
        hidden = [
            t.reason for e in results[name].exercises for t in e.tests if t.test.startswith("test_hidden")
        ]
        assert hidden and all(r.startswith("hidden test: ") for r in hidden), hidden
        assert not any("43" in r or "code" in r for r in hidden), hidden  # no exit code either


def test_hidden_reasons_are_fixed_phrases_per_kind(graded_class):
    results = graded_class[0]
    phrase = {
        "wire_class": "raised an exception",
        "exception_name": "raised an exception",
        "class_name": "answered something that is not plain data",
        "exit_code": "the process died",
        "exit_message": "raised an exception",
    }
    for name, expected in phrase.items():
        reasons = {
            t.reason for e in results[name].exercises for t in e.tests if t.test.startswith("test_hidden")
        }
        assert reasons == {f"hidden test: {expected}"}, (name, reasons)


# -- a CPU hog in another grading, stopped by SIGTERM -----------------------------------------


@pytest.mark.skipif(not MODES, reason="no namespaces here: a hog's loops would outlive its sandbox")
def test_a_cpu_hog_costs_an_honest_classmate_nothing(tmp_path):
    (tmp_path / "hog" / TARGET).mkdir(parents=True)
    (tmp_path / "hog" / TARGET / MODULE).write_text(HOG.replace("LOOPS", "40").replace("MARK", HOG_MARK))
    (tmp_path / "honest" / TARGET).mkdir(parents=True)
    shutil.copyfile(SOURCE / TARGET / MODULE, tmp_path / "honest" / TARGET / MODULE)
    (tmp_path / "tmp").mkdir()
    env = dict(os.environ, PYTHONPATH=str(ROOT), TMPDIR=str(tmp_path / "tmp"))
    hog = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mslab",
            "grade",
            str(tmp_path / "hog"),
            "--source",
            str(SOURCE),
            "--exercise",
            TARGET,
            "--timeout",
            "30",
            "--jobs",
            "1",
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        _wait_for(lambda: _hog_loops() >= 10, 60, "the hog did not start its loops")
        names = [p.name for p in (tmp_path / "tmp").glob(f"{PREFIX}*")]  # the hog's grading, live
        assert len(names) == 1, names
        (honest,) = grade([tmp_path / "honest"], source=SOURCE, jobs=1, timeout=2.0, only=[TARGET])
        assert _hog_loops() >= 1, "the hog stopped before its classmate was graded: the test proved nothing"
        assert honest.total == honest.max_points > 0, [
            (t.test, t.reason) for e in honest.exercises for t in e.tests
        ]
    finally:
        hog.send_signal(signal.SIGTERM)  # the grader stops its runners and removes its cgroups
        try:
            hog.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(hog.pid, signal.SIGKILL)
            hog.wait()
    _wait_for(lambda: _hog_loops() == 0, 30, "the hog's loops outlived its grader")
    assert leftovers(tmp_path / "tmp", names, mark=HOG_MARK) == []  # its folder and cgroups too


# -- an unprivileged grader -------------------------------------------------------------------

USER = "mslab-grade-test"


def _closed_ancestor(path: str) -> str | None:
    """The outermost folder on ``path`` that other users cannot enter, if any."""
    parts = Path(path).parts
    for k in range(2, len(parts) + 1):
        folder = os.path.join(*parts[:k])
        if os.path.isdir(folder) and not os.stat(folder).st_mode & 0o001:
            return folder
    return None


def _open_views(work: Path, paths: list[str]) -> str:
    """Shell commands that make ``paths`` reachable by other users in a private mount namespace.

    Each closed folder on the way is covered by an open tmpfs on which the folders beneath
    it that lead to ``paths`` are bound back; skips the test if a folder closed to others
    lies deeper still.
    """
    inners: dict[str, set[str]] = {}
    for path in paths:
        real = os.path.realpath(path)
        closed = _closed_ancestor(real)
        if closed:
            inner = os.path.join(closed, Path(real).relative_to(closed).parts[0])
            if _closed_below(inner, real):
                pytest.skip(f"{real} lies in more than one folder closed to other users")
            inners.setdefault(closed, set()).add(inner)
    script, n = "", 0
    for closed, folders in sorted(inners.items()):
        keeps = []
        for inner in sorted(folders):
            n += 1
            keeps.append((f"{work}/.keep{n}", inner))
            script += f"mkdir -p {work}/.keep{n} && mount --bind '{inner}' {work}/.keep{n} && "
        script += f"mount -t tmpfs -o mode=755 tmpfs '{closed}' && "
        for keep, inner in keeps:
            script += f"mkdir -p '{inner}' && mount --bind {keep} '{inner}' && "
    return script


def _closed_below(top: str, path: str) -> bool:
    """Whether a folder from ``top`` down to ``path`` (both included) is closed to other users."""
    parts = Path(path).relative_to(top).parts
    for k in range(len(parts) + 1):
        folder = os.path.join(top, *parts[:k])
        if os.path.isdir(folder) and not os.stat(folder).st_mode & 0o001:
            return True
    return False


@pytest.mark.skipif(
    os.geteuid() != 0
    or not shutil.which("useradd")
    or not shutil.which("setpriv")
    or not shutil.which("unshare"),
    reason="needs root, useradd, setpriv and unshare to create a user and grade as it",
)
@pytest.mark.skipif(not MODES, reason="no namespaces here")
def test_grading_as_an_unprivileged_user(tmp_path):
    try:
        pwd.getpwnam(USER)
    except KeyError:
        subprocess.run(
            ["useradd", "--system", "--no-create-home", "--shell", "/usr/sbin/nologin", USER],
            check=True,
            capture_output=True,
            timeout=60,
        )
    uid = pwd.getpwnam(USER).pw_uid
    work = Path(tempfile.mkdtemp(prefix="mslab-unpriv-", dir="/tmp"))
    try:
        os.chmod(work, 0o755)
        (work / "alice" / TARGET).mkdir(parents=True)
        shutil.copyfile(SOURCE / TARGET / MODULE, work / "alice" / TARGET / MODULE)
        for p in (work / "alice", work / "alice" / TARGET):
            os.chmod(p, 0o755)
        grade_cmd = [
            sys.executable,
            "-m",
            "mslab",
            "grade",
            str(work / "alice"),
            "--source",
            str(SOURCE),
            "--exercise",
            TARGET,
            "--json",
        ]
        # where the interpreter, the venv or this checkout sits in a folder closed to other users
        # (pyenv under /root, a fresh clone in a `mktemp -d` folder), the test opens a view of
        # it in a private mount namespace: the system is not changed
        setup = _open_views(work, [sys.base_prefix, sys.prefix, str(ROOT)])
        env = dict(
            os.environ,
            PYTHONPATH=str(ROOT),
            HOME=str(work),
            TMPDIR="/tmp",
            MSLAB_CACHE_DIR=str(work / "cache"),
            NUMBA_CACHE_DIR=str(work / "cache"),
        )
        script = setup + "exec setpriv --reuid={0} --regid={0} --clear-groups {1}".format(
            uid, " ".join(f"'{a}'" for a in grade_cmd)
        )
        proc = subprocess.run(
            ["unshare", "--mount", "--propagation", "private", "sh", "-c", script],
            env=env,
            capture_output=True,
            text=True,
            timeout=240,
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        doc = json.loads(proc.stdout)
        assert doc["total"] == doc["max"] > 0, doc
        assert "isolated by" in doc["isolation"]
        warnings = [line for line in proc.stderr.splitlines() if "warning" in line]
        if doc["resources"].startswith("no cgroup"):
            assert len(warnings) == 1 and "no cgroup" in warnings[0], proc.stderr
        else:
            assert warnings == [], proc.stderr
    finally:
        shutil.rmtree(work, ignore_errors=True)
