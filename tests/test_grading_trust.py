"""Grading v3 (issue 20): nothing the sandbox says is trusted; one student cannot touch another.

1. A CPU hog in a grading of its own beside an honest classmate's: the classmate keeps full
   marks; the hog's loops and cgroups end with its grader (stopped by SIGTERM).
2. Grading as an unprivileged user (a user created for the test, when run as root).
3. :func:`leftovers`, the check every class grading ends with, shown able to fail.

The class of 30 of this round (five leakers of hidden inputs, a CPU hog in its own box,
honest classmates) is graded in ``test_grading_hostile_class`` with that round's other
attacks, in every isolation mode; the honest variations of exercise 07's reference
(:func:`_honest_source`) in ``test_grading_classes``.

Each grading runs exercise 07 only; the runs are bounded (``timeout``) and synchronise on
processes seen in /proc, never on sleeps."""

from __future__ import annotations

import json
import os
import pwd
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from mslab.grading import grade
from mslab.grading.box import PREFIX
from mslab.grading.box import _mounts as cgroup_mounts
from mslab.grading.box import _own as own_cgroup
from mslab.grading.isolation import _probe

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
TARGET, MODULE = "07_stability_function", "stability_function.py"
#: the mark in the command lines of the hog's loops
HOG_MARK = "mslab-hog-loop"
MODES = [m for m in ("bwrap", "namespaces") if sys.platform.startswith("linux") and _probe(m)]

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


def leftovers(tmp: Path, names: list[str], mark: str = HOG_MARK) -> list[str]:
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
