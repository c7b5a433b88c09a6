"""``--isolation rlimits`` as root (a platform's container without user namespaces).

The student runs as a throwaway uid on a root-owned copy of what it may read; the
instructor's tree and the class are closed to other users while grading; every process
of that uid dies with the sandbox. Where the interpreter lies in a folder closed to other
users (pyenv under /root), the grader refuses in one line, and this test opens a view of
it in a private mount namespace (the system is not changed).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from test_grading_trust import _open_views

from mslab.grading.isolation import UID_BASE, UID_SPAN

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
TARGET, MODULE = "07_stability_function", "stability_function.py"
READER = '''
import os, time

def _peek():
    out = ["uid=%d" % os.getuid()]
    for path in ({hidden!r}, {classmate!r}):
        try:
            out.append("read:" + open(path).read()[:80])
        except OSError as err:
            out.append(type(err).__name__)
    return " | ".join(out)

def stability_function(A, b, z):
    if os.fork() == 0:  # a daemon in a session of its own
        os.setsid()
        while True:
            time.sleep(1)
    raise RuntimeError(_peek())

def real_stability_interval(A, b, tol=1e-12):
    raise RuntimeError(_peek())
'''


def _processes_of(uids: set[int]) -> list[str]:
    """Processes of these uids, with their state (a zombie waits for init to reap it)."""
    found = []
    for entry in os.listdir("/proc"):
        try:
            with open(f"/proc/{entry}/status") as fh:
                fields = dict(line.split(":", 1) for line in fh if ":" in line)
            uid = int(fields["Uid"].split()[0])
        except (OSError, ValueError, KeyError):
            continue
        if uid in uids and not fields["State"].strip().startswith("Z"):
            found.append(f"{entry} {fields['State'].strip()}")
    return found


@pytest.fixture(scope="module")
def graded_as_root():
    if os.geteuid() != 0 or not shutil.which("unshare"):
        pytest.skip("needs root (the platforms' containers grade as root) and unshare")
    base = Path(tempfile.mkdtemp(prefix="mslab-rlimits-"))
    try:
        for sub in ("", "src", "class", "tmp"):
            (base / sub).mkdir(exist_ok=True)
            os.chmod(base / sub, 0o755)  # readable by everyone, as a checkout usually is
        shutil.copytree(SOURCE / TARGET, base / "src" / TARGET)
        (base / "class" / "honest" / TARGET).mkdir(parents=True)
        honest = base / "class" / "honest" / TARGET / MODULE
        shutil.copyfile(SOURCE / TARGET / MODULE, honest)
        (base / "class" / "reader" / TARGET).mkdir(parents=True)
        hidden = base / "src" / TARGET / "test_hidden.py"
        (base / "class" / "reader" / TARGET / MODULE).write_text(
            READER.format(hidden=str(hidden), classmate=str(honest)))
        cmd = [sys.executable, "-m", "mslab", "grade", str(base / "class"), "--source", str(base / "src"),
               "--exercise", TARGET, "--isolation", "rlimits", "--json", "--jobs", "1"]
        views = _open_views(base / "tmp", [sys.base_prefix, sys.prefix, str(ROOT)])
        env = dict(os.environ, PYTHONPATH=str(ROOT), TMPDIR=str(base / "tmp"))
        proc = subprocess.run(["unshare", "--mount", "--propagation", "private", "sh", "-c",
                               views + "exec " + " ".join(f"'{a}'" for a in cmd)],
                              env=env, capture_output=True, text=True, timeout=600)
        modes = {p: os.stat(base / p).st_mode & 0o777 for p in ("src", "class")}
        left = [p.name for p in (base / "tmp").iterdir() if not p.name.startswith(".keep")]
        yield proc, hidden.read_text(), modes, left
    finally:
        shutil.rmtree(base, ignore_errors=True)


def test_honest_full_marks_and_the_student_is_a_throwaway_uid(graded_as_root):
    proc, _, _, _ = graded_as_root
    assert proc.returncode == 0, proc.stderr[-2000:]
    docs = {d["student"]: d for d in json.loads(proc.stdout)["submissions"]}
    assert docs["honest"]["total"] == docs["honest"]["max"] > 0, docs["honest"]
    reasons = [t["reason"] for e in docs["reader"]["exercises"] for t in e["tests"]
               if t["test"].startswith("test_public")]
    quoted = [r for r in reasons if "uid=" in r]
    assert quoted, reasons
    for reason in quoted:
        uid = int(reason.split("uid=")[1].split()[0])
        assert UID_BASE <= uid < UID_BASE + UID_SPAN
        assert "read:" not in reason and reason.count("PermissionError") == 2, reason


def test_no_hidden_text_in_any_output(graded_as_root):
    proc, hidden, _, _ = graded_as_root
    lines = [ln.strip() for ln in hidden.splitlines() if len(ln.strip()) > 20]
    assert lines
    for line in lines:
        assert line not in proc.stdout and line not in proc.stderr


def test_no_process_left_and_the_folders_get_their_modes_back(graded_as_root):
    proc, _, modes, left = graded_as_root
    uids = {int(part.split()[0]) for part in proc.stdout.split("uid=")[1:]}  # those the reader reported
    assert uids
    assert _processes_of(uids) == []  # each sandbox's setsid daemon died with it
    assert modes == {"src": 0o755, "class": 0o755}
    assert left == []


BOMB = """
import os, sys
r, w = os.pipe()
n = 0
for _ in range(300):
    try:
        pid = os.fork()
    except OSError:
        break
    if pid == 0:
        os.close(w)
        os.read(r, 1)
        os._exit(0)
    n += 1
os.close(w)
print(n)
"""


def _closed_to_others(path: str) -> bool:
    parts = Path(os.path.realpath(path)).parts
    return any(not os.stat(os.path.join(*parts[:k])).st_mode & 0o001 for k in range(2, len(parts)))


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to run the sandbox's limits as a fresh user")
def test_a_user_without_cgroups_has_a_process_cap_anyway():
    """As a user without a cgroup the sandbox's limits stop a fork bomb within 64 new processes."""
    from mslab.grading.box import MAX_PROCESSES
    from mslab.grading.remote import _limits

    uid = UID_BASE + UID_SPAN - 1  # a user with no process yet
    limits = _limits(1024, 60, 1, mode="rlimits", box=None)

    def as_user() -> None:
        os.setgroups([])
        os.setgid(uid)
        os.setuid(uid)
        limits()

    python = next((p for p in (os.path.realpath(sys.executable), "/usr/bin/python3")
                   if not _closed_to_others(p)), None)
    if python is None:
        pytest.skip("no interpreter that another user may run")
    proc = subprocess.run([python, "-S", "-c", BOMB], preexec_fn=as_user,
                          capture_output=True, text=True, timeout=120, cwd="/")
    assert proc.returncode == 0, proc.stderr
    assert 0 < int(proc.stdout) <= MAX_PROCESSES  # 300 without the cap


REAPED = """
import os, subprocess, sys
from mslab.grading import reaper

assert reaper.become_subreaper()
daemon = ("import os, time\\nos.setsid()\\nif os.fork():\\n    os._exit(0)\\n"
          "print(os.getpid(), flush=True)\\ntime.sleep(10 ** 6)\\n")
child = subprocess.Popen([sys.executable, "-c", daemon], stdout=subprocess.PIPE, text=True)
pid = int(child.stdout.readline())
child.wait()  # the daemon's parent is gone: the daemon is an orphan in a session of its own
with open(f"/proc/{pid}/stat") as fh:
    adopted = int(fh.read().rsplit(")", 1)[1].split()[1]) == os.getpid()
reaper.kill_orphans()
print(adopted, os.path.exists(f"/proc/{pid}"))
"""


def test_the_runner_kills_the_orphans_it_adopts():
    """rlimits as a user, no cgroup: a daemon that left its sandbox's session (setsid, double fork)
    is adopted by the runner (child subreaper) and killed with the sandbox group, not left to init."""
    proc = subprocess.run([sys.executable, "-c", REAPED], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.stdout.split() == ["True", "False"], proc.stdout + proc.stderr


def test_rlimits_grades_one_student_at_a_time():
    """rlimits: one student at a time, as root too (sandboxes share /tmp and /dev/shm: two students
    at once could pass a hidden input while both run; as a user a fork bomb beside an honest
    classmate starved it: 13 of 15 in the hostile class, intermittently); elsewhere ``--jobs``."""
    from mslab.grading.autograde import parallel_jobs

    assert parallel_jobs(4, "rlimits", None, euid=1000) == 1
    assert parallel_jobs(4, "rlimits", object(), euid=1000) == 1
    assert parallel_jobs(4, "rlimits", None, euid=0) == 1
    assert parallel_jobs(4, "bwrap", None, euid=1000) == 4
    assert parallel_jobs(4, "namespaces", object(), euid=0) == 4


@pytest.mark.skipif(os.geteuid() != 0, reason="a throwaway uid needs root")
def test_a_throwaway_uids_files_in_shared_folders_go_with_its_sandbox(tmp_path):
    """What a sandbox run as a throwaway uid leaves in /tmp, /dev/shm or a world-writable folder
    inside them (a hidden input for a classmate graded later) is removed when the sandbox ends;
    another uid's file and a link's target stay. Fails on the old ``release_uid`` (files kept)."""
    from mslab.grading import isolation

    uid = UID_BASE + UID_SPAN - 7
    shared = Path(tempfile.mkdtemp(prefix="mslab-shared-", dir="/tmp"))
    shared.chmod(0o1777)                                   # like /tmp/.X11-unix: anyone may write
    keep = tmp_path / "target.txt"
    keep.write_text("the grader's")
    planted = [Path("/tmp") / f"mslab-plant-{uid}", Path("/dev/shm") / f"mslab-plant-{uid}",
               shared / "inner.txt"]
    pid = os.fork()
    if pid == 0:                                           # the sandbox: plant files as the uid
        try:
            isolation.become(uid)
            for path in planted:
                path.write_text("hidden input 0.3141")
            os.mkdir(f"/tmp/mslab-plant-dir-{uid}")
            Path(f"/tmp/mslab-plant-dir-{uid}/x").write_text("y")
            os.symlink(keep, f"/tmp/mslab-plant-link-{uid}")
        finally:
            os._exit(0)
    os.waitpid(pid, 0)
    others = shared / "grader.txt"
    others.write_text("root's")
    made = [*planted, Path(f"/tmp/mslab-plant-dir-{uid}"), Path(f"/tmp/mslab-plant-link-{uid}")]
    try:
        assert all(os.path.lexists(p) for p in made), "the uid could not plant its files"
        isolation.release_uid(uid)
        assert [p for p in made if os.path.lexists(p)] == []
        assert others.read_text() == "root's" and keep.read_text() == "the grader's"
    finally:
        for p in made:
            if os.path.isdir(p) and not os.path.islink(p):
                shutil.rmtree(p, ignore_errors=True)
            elif os.path.lexists(p):
                os.unlink(p)
        shutil.rmtree(shared, ignore_errors=True)
