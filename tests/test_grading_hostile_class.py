"""A hostile class of 30 in one grading, in every isolation mode (issue 35 "Done means", issue 40).

One student per attack beside honest classmates, all graded in ONE ``mslab grade`` run of
exercise 02 (the CLI, as an instructor runs it, ``--json`` and ``--csv``), once per mode:
bubblewrap, the namespace jail, ``--isolation rlimits`` as root and ``--isolation rlimits``
as an unprivileged user (``setpriv`` to ``nobody``). The grader inherits an open file and a
pipe's write end without close-on-exec, as a careless parent would hand them over.

- Every honest student (a plain folder, folders named like exercises, a ``.zip``, a
  ``.ipynb``, one ``.py``, a name a spreadsheet would evaluate) has full marks; every entry
  of the class folder has a row (a ``.dotted`` folder too, with its reason).
- Every attacker scores at most what it really implemented: the attacks that implement
  nothing at most an empty submission, those beside a real ``forward_euler_step`` at most
  a submission with only that function.
- Nothing of the hidden tests (text, inputs: a marker planted in a hidden test's inputs)
  in any output; the same marker in a public test does reach its report (the quoter's
  channel is real, so this can fail). No payload ran in the trusted runner.
- The inherited descriptors are unreachable from every sandbox: nothing was written into
  the pipe, the secret file's name and text appear nowhere.
- In the namespace modes (as issue 20's class was graded), five leakers send their inputs
  back in the sandbox's words (an exception class named ``<wire>``, a class or exception
  name, ``sys.exit``'s message, the exit code): the public marker reaches their public
  reports (the channel is real), every hidden reason is its kind's fixed phrase, and the
  hidden marker is in no output (JSON, CSV, the text report, the journal's lines as they
  were written). There too, a CPU hog forks busy loops in sessions of their own at import,
  only sleeping itself: its tests end on the CPU limit of its whole sandbox (the loops ran,
  in its box), and every honest classmate keeps full marks. In the rlimits modes their six
  seats hold honest classmates.
- Nothing is left: no marked daemon or loop, no grading folder in the private ``TMPDIR``, no
  cgroup of the grading (:func:`test_grading_trust.leftovers`).

As the unprivileged user, rlimits mode runs the student as the grader's own uid: it reads
what the grader reads (the hidden tests, classmates' files), as the README's table says;
that is measured here too, not assumed. Synchronisation is by processes and pipes, never sleeps.
"""

from __future__ import annotations

import json
import os
import pwd
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest
from test_grading_payloads import payload_module
from test_grading_rlimits import BOMB, _processes_of
from test_grading_trust import _hog_loops, _open_views, leftovers

from mslab.grading.isolation import UID_BASE, UID_SPAN, _probe

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "exercises"
EX, MODULE = "02_euler_steps", "euler_steps.py"
REFERENCE = (SOURCE / EX / MODULE).read_text()
HIDDEN_MARK, PUBLIC_MARK = "5772156", "1414213"
SECRET = "mslab-inherited-secret-6931471"
DAEMON_MARK = "mslab-class-daemon"
#: CPU seconds per test: the reference passes each test of exercise 02 with a few hundredths
TIMEOUT = "0.5"

MARKED_TEST = """

@pytest.mark.points(1)
def test_marked_{kind}(student):
    from mslab.grading.checks import check_array as _check, reference_run as _reference
    from mslab.grading.problems import problem as _problem
    prob = _problem("oscillator", stiffness=4.0, displacement=0.3)
    v0 = np.array([[0.0], [0.{mark}]])
    ref = _reference("euler", prob, prob.x0, v0, 0.01)
    x, v = student.forward_euler_step(prob.x0, v0, prob, 0.01)
    _check(x, ref.x, what="x_new")
    _check(v, ref.v, what="v_new")
"""

#: the other two steps of the reference, replaced (a later ``def`` wins)
ONLY_FORWARD = """

def symplectic_euler_step(x, v, accel, dt):
    raise NotImplementedError

def symplectic_euler_x_step(x, v, accel, dt):
    raise NotImplementedError
"""
EMPTY = """
def forward_euler_step(x, v, accel, dt):
    raise NotImplementedError
""" + ONLY_FORWARD

#: every function the tests ask for answers by ``_attack(*args)`` (module ``__getattr__``)
EVERY_FUNCTION = """

def __getattr__(name):
    if name.startswith("__"):
        raise AttributeError(name)
    return lambda *args, **kwargs: _attack(*args)
"""

#: records the short decimals of every input it sees (memory, files beside it, /tmp, home)
#: and fails every call quoting all it ever saw: hidden inputs, if one process served both
QUOTER = r"""
import os, re
import numpy as np
_SEEN = set()
_LOGS = [os.path.join(d, "mslab-quoter-seen.log") for d in
         (os.path.dirname(os.path.abspath(__file__)), os.getcwd(), os.path.expanduser("~"), "/tmp",
          "/var/tmp", "/dev/shm")]

def _attack(*args):
    for a in args:
        try:
            _SEEN.update(re.findall(r"0\.\d{7}(?!\d)", repr(np.asarray(a).tolist())))
        except Exception:
            pass
    for log in _LOGS:
        try:
            with open(log) as fh:
                _SEEN.update(fh.read().split())
        except OSError:
            pass
        try:
            with open(log, "a") as fh:
                fh.write(" ".join(_SEEN) + "\n")
            os.chmod(log, 0o666)  # readable by a classmate's uid too, as a colluding student makes it
        except OSError:
            pass
    raise RuntimeError("seen " + " ".join(sorted(_SEEN)))
"""

#: reads the hidden test and a classmate's file, lists the grader's own temporary folder, and
#: leaves a daemon in a session of its own (marked, so the test can find it)
READER = """
import os, sys

def _peek():
    out = ["uid=%d" % os.getuid()]
    for path in ({hidden!r}, {classmate!r}):
        try:
            out.append("read:" + open(path).read()[:60].replace("\\n", " "))
        except OSError as err:
            out.append(type(err).__name__)
    try:
        names = os.listdir({tmp!r})
    except OSError as err:
        names = [type(err).__name__]
    for name in names:  # the grader's own folder (runner folders, tests)
        if name.startswith("mslab-grade-"):
            try:
                out.append("ls-grader:" + ",".join(os.listdir(os.path.join({tmp!r}, name))))
            except OSError as err:
                out.append(type(err).__name__)
    return " | ".join(out)

def _attack(*args):
    if os.fork() == 0:
        os.setsid()
        os.execv(sys.executable, [sys.executable, "-c", "import time\\nwhile True: time.sleep(1)  # {mark}"])
    raise RuntimeError(_peek())
"""

#: looks at every descriptor it has beyond 0-2 for the pipe and the file the grader inherited
#: (their inode numbers, @PIPE@ and @FILE@, filled in by the test): writes into that pipe,
#: reads that file (writing into any other pipe would only break its own channel to the runner)
FD_PROBER = r"""
import os, stat

def _probe():
    found, n = [], 0
    for fd in range(3, 1024):
        try:
            st = os.fstat(fd)
        except OSError:
            continue
        n += 1
        if stat.S_ISFIFO(st.st_mode) and st.st_ino == @PIPE@:
            try:
                os.write(fd, b"LEAK")
                found.append("wrote into the pipe at %d" % fd)
            except OSError:
                found.append("pipe at %d" % fd)
        if stat.S_ISREG(st.st_mode) and st.st_ino == @FILE@:
            try:
                found.append("read the secret at %d: %s" % (fd, os.pread(fd, 100, 0).decode()))
            except OSError:
                found.append("secret at %d" % fd)
    return found + ["%d fds" % n]

def _attack(*args):
    raise RuntimeError("probed " + " ".join(_probe()))
"""


def fd_prober(pipe_end: int, secret_fd: int) -> str:
    """The prober, looking for these two descriptors (by inode)."""
    return (FD_PROBER.replace("@PIPE@", str(os.fstat(pipe_end).st_ino))
            .replace("@FILE@", str(os.fstat(secret_fd).st_ino)))


#: sleeps in one test only (the public one with dt = 0.01): one wall-clock backstop of cost
SLEEPER = ONLY_FORWARD + """
def symplectic_euler_x_step(x, v, accel, dt):
    import time
    if dt < 0.05:
        time.sleep(10_000)
    raise NotImplementedError
"""
SPINNER = ONLY_FORWARD + """
def symplectic_euler_step(x, v, accel, dt):
    while True:
        pass
"""
MEMORY_BOMB = ONLY_FORWARD + """
def symplectic_euler_step(x, v, accel, dt):
    blocks = []
    while True:
        blocks.append(bytearray(2 ** 28))
"""

#: every leaker answers each call by sending its inputs back (``_leak``: the second argument's
#: values, the velocities, where the marked tests put their markers) in the sandbox's words
LEAK = """
import os, re, sys
import numpy as np

def _leak(args):
    return repr(np.asarray(args[1]).tolist()) if len(args) > 1 else repr(args)
"""
LEAKERS = {  # the body of each one's _attack(*args)
    "wire_class": 'raise type("<wire>", (Exception,), {})(_leak(args))',
    "class_name": 'return type("leak_" + re.sub(r"\\W", "_", _leak(args)), (), {})()',
    "exception_name": 'raise type("L_" + re.sub(r"\\W", "_", _leak(args)), (ValueError,), {})()',
    "exit_message": "sys.exit(_leak(args))",
    "exit_code": "os._exit(int(round(np.asarray(args[1]).ravel()[-1] * 100)) % 256)",
}
#: the hidden reasons each leaker's kind of failure gets (the runner's own decision)
LEAKER_PHRASES = {"wire_class": "raised an exception", "exception_name": "raised an exception",
                  "class_name": "answered something that is not plain data", "exit_code": "the process died",
                  "exit_message": "raised an exception"}
#: busy loops of the hog (4x the cores of a 2-core machine; each restart of its sandbox forks them
#: again, so more only slows its own grading), marked like the reader's daemon
HOG_LOOPS = 8
HOG = f"""
import subprocess, sys
for _ in range({HOG_LOOPS}):
    try:
        subprocess.Popen([sys.executable, "-c", "# {DAEMON_MARK}\\nwhile True: pass"],
                         start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        break

def _attack(*args):
    import time
    time.sleep(1000)
"""

#: a spy on the grader's owned folders (their names also name its cgroups), its journal's lines as
#: written and its text report (the CLI prints JSON), then the CLI
SPY = """
import json, sys
import mslab.commands.grade as command
import mslab.grading.autograde as autograde
from mslab.grading.report import Journal, format_report

class Spied(autograde.Owned):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        with open(sys.argv[1], "a") as fh:
            fh.write(self.name + "\\n")

def add(self, key, outcome, _add=Journal.add):
    with open(sys.argv[1] + ".journal", "a") as fh:
        fh.write(json.dumps(outcome) + "\\n")
    return _add(self, key, outcome)

def grade(*args, _grade=command.grade, **kwargs):
    results = _grade(*args, **kwargs)
    with open(sys.argv[1] + ".report", "w") as fh:
        fh.write("\\n".join(format_report(r) for r in results))
    return results

autograde.Owned, Journal.add, command.grade = Spied, add, grade
from mslab.cli import main
sys.exit(main(sys.argv[2:]))
"""

#: students that implement nothing / only forward_euler_step (their bound)
AT_MOST_EMPTY = ("payload_texts", "payload_raises", "payload_sizes", "quoter", "reader", "fd_prober",
                 "edit_tests", "symlink")
#: the leakers and the hog (issue 20's class): graded in the namespace modes, as that class was; in
#: the rlimits modes their six seats hold honest classmates (each restart of their sandboxes costs)
ROUND20 = ("hog", *LEAKERS)
SPARE_HONEST = [f"honest{k}" for k in range(3, 3 + len(ROUND20))]
AT_MOST_PARTIAL = ("sleeper", "spinner", "memory_bomb", "fork_bomb")
HONEST = [f"honest{k}" for k in range(3)] + ["01_spring_force", EX, "zipped.zip", "notebook.ipynb",
                                             "flat.py", '=HYPERLINK("evil.example","x")']


def _notebook(code: str) -> str:
    cells = [{"cell_type": "markdown", "metadata": {}, "source": ["# my work\n"]},
             {"cell_type": "code", "metadata": {}, "execution_count": None, "outputs": [],
              "source": code.splitlines(keepends=True)}]
    return json.dumps({"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 5})


def _with_round20(mode: str) -> bool:
    return not mode.startswith("rlimits")


def _honest(mode: str) -> list[str]:
    """The honest students: in rlimits as root one spare gives its place to ``quoter_b``."""
    spares = [] if _with_round20(mode) else SPARE_HONEST[:-1] if mode == "rlimits" else SPARE_HONEST
    return HONEST + spares


def _build(base: Path, prober: str, mode: str) -> tuple[Path, Path]:
    """The marked source of exercise 02 and the class of 30 (each entry's file readable by all)."""
    src = base / "src"
    shutil.copytree(SOURCE / EX, src / EX, ignore=shutil.ignore_patterns("__pycache__"))
    for name, kind, mark in (("test_hidden.py", "hidden", HIDDEN_MARK),
                             ("test_public.py", "public", PUBLIC_MARK)):
        with open(src / EX / name, "a") as fh:
            fh.write(MARKED_TEST.format(kind=kind, mark=mark))
    cls = base / "class"
    tmp = base / "tmp"
    files = {name: f"# {name}: my own work\n" + REFERENCE for name in _honest(mode) if "." not in name}
    files[HONEST[-1]] = REFERENCE
    files.update({
        "partial": REFERENCE + ONLY_FORWARD, "empty": EMPTY, "edit_tests": EMPTY,
        "sleeper": REFERENCE + SLEEPER, "spinner": REFERENCE + SPINNER,
        "memory_bomb": REFERENCE + MEMORY_BOMB, "fork_bomb": BOMB + REFERENCE + ONLY_FORWARD,
        "quoter": QUOTER + EVERY_FUNCTION, "fd_prober": prober + EVERY_FUNCTION,
        "reader": READER.format(hidden=str(src / EX / "test_hidden.py"),
                                classmate=str(cls / "honest0" / EX / MODULE), tmp=str(tmp),
                                mark=DAEMON_MARK) + EVERY_FUNCTION,
        ".dotted": REFERENCE,
    })
    if mode == "rlimits":  # a classmate graded after the quoter reads what it left in /tmp, /dev/shm
        files["quoter_b"] = QUOTER + EVERY_FUNCTION
    if _with_round20(mode):
        files.update({name: f"{LEAK}\ndef _attack(*args):\n    {body}\n{EVERY_FUNCTION}"
                      for name, body in LEAKERS.items()})
        files["hog"] = HOG + EVERY_FUNCTION
    for group in ("texts", "raises", "sizes"):
        files[f"payload_{group}"] = payload_module(tmp / "payload-ran", group)
    for name, text in files.items():
        (cls / name / EX).mkdir(parents=True)
        (cls / name / EX / MODULE).write_text(text)
    # the test editor ships tests and a conftest that pass everything; a file linking to the reference
    for name in ("test_public.py", "test_hidden.py", "conftest.py"):
        (cls / "edit_tests" / EX / name).write_text(
            "import pytest\n\n@pytest.mark.points(100)\ndef test_free():\n    pass\n")
    (cls / "symlink" / EX).mkdir(parents=True)
    (cls / "symlink" / EX / MODULE).symlink_to(SOURCE / EX / MODULE)
    with zipfile.ZipFile(cls / "zipped.zip", "w") as zf:
        zf.writestr(f"{EX}/{MODULE}", REFERENCE)
    (cls / "notebook.ipynb").write_text(_notebook(REFERENCE))
    (cls / "flat.py").write_text(REFERENCE)
    assert len(list(cls.iterdir())) == 30
    return src, cls


MODES = ["bwrap", "namespaces", "rlimits", "rlimits-user"]


def _skip_reason(mode: str) -> str:
    if not sys.platform.startswith("linux"):
        return "Linux only"
    if mode in ("bwrap", "namespaces") and not _probe(mode):
        return f"{mode} is not available on this machine"
    if mode == "rlimits" and os.geteuid() != 0:
        return "rlimits as root needs root (the platforms' containers grade as root)"
    if os.geteuid() == 0 and not (shutil.which("unshare") and shutil.which("setpriv")):
        return "needs unshare and setpriv to grade as root with views, and as another user"
    return ""


@pytest.fixture(scope="module", params=MODES)
def graded(request):
    """The class graded by ``mslab grade`` in one mode, with an inherited file and pipe."""
    mode = request.param
    if why := _skip_reason(mode):
        pytest.skip(why)
    as_user = mode == "rlimits-user" and os.geteuid() == 0
    base = Path(tempfile.mkdtemp(prefix=f"mslab-hostile-{mode}-", dir="/tmp"))
    try:
        os.chmod(base, 0o755)  # readable by everyone, as a checkout usually is
        secret = base / "inherited-secret.txt"
        secret.write_text(SECRET)
        os.chmod(secret, 0o600)
        fd = os.open(secret, os.O_RDONLY)  # inheritable: no O_CLOEXEC
        r, w = os.pipe()
        src, cls = _build(base, fd_prober(w, fd), mode)
        tmp = base / "tmp"
        tmp.mkdir()
        os.chmod(tmp, 0o1777)
        names_file, csv_path = tmp / "owned-names.txt", tmp / "book.csv"
        cmd = [sys.executable, "-c", SPY, str(names_file), "grade", str(cls), "--source", str(src),
               "--exercise", EX, "--isolation", mode.removesuffix("-user"), "--timeout", TIMEOUT,
               "--jobs", "2", "--json", "--csv", str(csv_path)]
        views = ""
        if os.geteuid() == 0 and mode.startswith("rlimits"):
            views = _open_views(base / "views", [sys.base_prefix, sys.prefix, str(ROOT)])
        user = "setpriv --reuid=nobody --regid=nogroup --clear-groups " if as_user else ""
        script = views + "exec " + user + " ".join(f"'{a}'" for a in cmd)
        argv = (["unshare", "--mount", "--propagation", "private"] if views else []) + ["sh", "-c", script]
        env = dict(os.environ, PYTHONPATH=str(ROOT), TMPDIR=str(tmp), HOME=str(tmp),
                   MSLAB_CACHE_DIR=str(tmp / "cache"), NUMBA_CACHE_DIR=str(tmp / "cache"))
        os.set_inheritable(fd, True)
        os.set_inheritable(w, True)
        try:
            proc = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=1200,
                                  pass_fds=(fd, w))
        finally:
            os.close(fd)
            os.close(w)
        os.set_blocking(r, False)
        try:
            piped = os.read(r, 1000)  # b"" once no process holds the write end
        except BlockingIOError:
            piped = "still held open by a process"
        os.close(r)
        names = names_file.read_text().split() if names_file.exists() else []
        left = leftovers(tmp, names, mark=DAEMON_MARK)
        csv_text = csv_path.read_text() if csv_path.exists() else ""
        spied = [Path(f"{names_file}.{kind}") for kind in ("journal", "report")]
        journal, report = (p.read_text() if p.exists() else "" for p in spied)
        yield {"mode": mode, "proc": proc, "csv": csv_text, "piped": piped, "names": names, "left": left,
               "journal": journal, "report": report,
               "hidden": (src / EX / "test_hidden.py").read_text(), "marker": (tmp / "payload-ran").exists()}
    finally:
        shutil.rmtree(base, ignore_errors=True)
        for shared in ("/tmp", "/var/tmp", "/dev/shm"):  # what the quoter left where all may write
            Path(shared, "mslab-quoter-seen.log").unlink(missing_ok=True)


def _docs(graded) -> dict:
    proc = graded["proc"]
    assert proc.returncode == 0, proc.stderr[-3000:]
    return {d["student"]: d for d in json.loads(proc.stdout)["submissions"]}


def _reasons(doc: dict, prefix: str = "test_") -> list[str]:
    return [t["reason"] for e in doc["exercises"] for t in e["tests"] if t["test"].startswith(prefix)]


def _student(docs: dict, name: str) -> dict:
    (found,) = [d for n, d in docs.items() if n == name or n == Path(name).stem]
    return found


def test_every_entry_has_a_row(graded):
    docs = _docs(graded)
    assert len(docs) == 30, sorted(docs)
    rows = graded["csv"].strip().splitlines()
    assert len(rows) == 31, rows  # a header and one row per entry
    assert not any(row.startswith(("=", "+", "-", "@")) for row in rows)
    dotted = _student(docs, ".dotted")
    assert dotted["total"] == 0


def test_every_honest_student_has_full_marks(graded):
    docs = _docs(graded)
    for name in _honest(graded["mode"]):
        doc = _student(docs, name)
        assert doc["total"] == doc["max"] > 0, (name, [r for r in _reasons(doc) if r])


def test_every_attacker_scores_at_most_what_it_implemented(graded):
    docs = _docs(graded)
    empty, partial, full = (_student(docs, n)["total"] for n in ("empty", "partial", "honest0"))
    assert empty == 0 < partial < full  # the bounds below mean something
    for name in AT_MOST_EMPTY + (ROUND20 if _with_round20(graded["mode"]) else ()):
        assert _student(docs, name)["total"] <= empty, (name, _reasons(_student(docs, name)))
    for name in AT_MOST_PARTIAL:
        assert _student(docs, name)["total"] <= partial, (name, _reasons(_student(docs, name)))
    assert not graded["marker"], "the runner executed a student's text"


def test_the_quoter_sees_public_inputs_only(graded):
    docs = _docs(graded)
    quoted = " ".join(_reasons(_student(docs, "quoter"), "test_public"))
    assert PUBLIC_MARK in quoted, quoted  # the channel is real: this test can fail
    assert HIDDEN_MARK not in quoted


def test_a_classmate_graded_later_reads_no_hidden_input(graded):
    """rlimits as root: the sandboxes share /tmp, /var/tmp and /dev/shm, where the quoter's hidden
    sandbox logs every input it saw; ``quoter_b``, graded after it, quotes every log it finds in its
    public message. Students are graded one at a time and a throwaway uid's files go with its
    sandbox, so no hidden input reaches it (before: the quoter's log, readable by all, did)."""
    if graded["mode"] != "rlimits":
        pytest.skip("bwrap and namespaces give every sandbox its own /tmp; rlimits as a user is not "
                    "isolated at all (README's isolation table)")
    quoted = " ".join(_reasons(_student(_docs(graded), "quoter_b"), "test_public"))
    assert PUBLIC_MARK in quoted, quoted  # its channel works: this test can fail
    assert HIDDEN_MARK not in quoted, quoted


def _outputs(graded) -> list[str]:
    assert graded["journal"] and graded["report"], "the spy saw no journal line or report"
    return [graded["proc"].stdout, graded["proc"].stderr, graded["csv"], graded["journal"], graded["report"]]


def test_nothing_of_the_hidden_tests_in_any_output(graded):
    public = (SOURCE / EX / "test_public.py").read_text() + REFERENCE + MARKED_TEST
    lines = [ln.strip() for ln in graded["hidden"].splitlines()
             if len(ln.strip()) > 20 and ln.strip() not in public and not ln.lstrip().startswith("def test_")]
    assert len(lines) > 10
    user_mode = graded["mode"] == "rlimits-user" and os.geteuid() == 0
    for text in _outputs(graded):
        assert HIDDEN_MARK not in text
        if not user_mode:
            for line in lines:
                assert line not in text, line


def test_classmates_hidden_tests_and_grader_folders_unreadable(graded):
    docs = _docs(graded)
    reasons = [r for r in _reasons(_student(docs, "reader"), "test_public") if "uid=" in r]
    assert reasons, _reasons(_student(docs, "reader"))
    for reason in reasons:
        uid = int(reason.split("uid=")[1].split()[0])
        if graded["mode"] == "rlimits-user" and os.geteuid() == 0:
            # the student is the grader's uid: it reads what the grader reads (README's table)
            assert uid == pwd.getpwnam("nobody").pw_uid
            assert reason.count("read:") == 2, reason
            continue
        assert "read:" not in reason and "ls-grader:" not in reason, reason
        if graded["mode"] == "rlimits":
            assert UID_BASE <= uid < UID_BASE + UID_SPAN


def _test(doc: dict, suffix: str) -> dict:
    (found,) = [t for e in doc["exercises"] for t in e["tests"] if t["test"].endswith(suffix)]
    return found


def test_the_leakers_send_the_public_marker_and_no_hidden_word(graded):
    """The channel is real (a public test quotes the student's own words); hidden reasons are fixed."""
    if not _with_round20(graded["mode"]):
        pytest.skip("the leakers are graded in the namespace modes (their seats hold honest students here)")
    docs = _docs(graded)
    for name in ("wire_class", "class_name", "exception_name", "exit_message"):
        assert PUBLIC_MARK in _test(_student(docs, name), "::test_marked_public")["reason"], name
    code = _test(_student(docs, "exit_code"), "::test_marked_public")["reason"]
    assert "exited with code 14" in code, code  # round(0.1414213 * 100): the runner saw the status
    for name, phrase in LEAKER_PHRASES.items():
        assert set(_reasons(_student(docs, name), "test_hidden")) == {f"hidden test: {phrase}"}, name
        assert "58" not in _test(_student(docs, name), "::test_marked_hidden")["reason"]  # no exit code


def test_the_hog_hogged_in_its_own_box(graded):
    """The hog only sleeps: its tests end on its sandbox's CPU limit, so its loops ran, in its box.

    (On a machine so busy that the hog's box gets under a twentieth of a core, a test may
    reach the wall-clock backstop first; at least one reaches the CPU limit.)
    """
    if not _with_round20(graded["mode"]):
        pytest.skip("the hog is graded in the namespace modes (its seat holds an honest student here)")
    reasons = set(_reasons(_student(_docs(graded), "hog"), "test_hidden"))
    assert reasons <= {"hidden test: timed out (CPU time limit)", "hidden test: timed out (wall-clock limit)"}
    assert "hidden test: timed out (CPU time limit)" in reasons


def test_inherited_descriptors_do_not_reach_the_sandbox(graded):
    docs = _docs(graded)
    probed = " ".join(_reasons(_student(docs, "fd_prober"), "test_public"))
    assert "probed" in probed and " fds" in probed, probed  # the prober ran
    assert "pipe" not in probed and "secret" not in probed, probed
    assert graded["piped"] == b"", graded["piped"]
    for text in _outputs(graded):
        assert SECRET not in text


def test_the_fd_prober_finds_descriptors_it_inherits(tmp_path):
    """Without the grader between them the prober finds both descriptors: the test above can fail."""
    secret = tmp_path / "inherited-secret.txt"
    secret.write_text(SECRET)
    fd = os.open(secret, os.O_RDONLY)
    r, w = os.pipe()
    try:
        proc = subprocess.run([sys.executable, "-c", fd_prober(w, fd) + "print(' '.join(_probe()))"],
                              pass_fds=(fd, w), capture_output=True, text=True, timeout=60)
    finally:
        os.close(fd)
        os.close(w)
    assert os.read(r, 100) == b"LEAK"
    os.close(r)
    assert f"wrote into the pipe at {w}" in proc.stdout, proc.stdout
    assert f"read the secret at {fd}: {SECRET}" in proc.stdout, proc.stdout


def test_nothing_is_left(graded):
    assert graded["names"], "no grading folder was seen: the leftover check looked for nothing"
    assert graded["left"] == []
    assert _hog_loops(DAEMON_MARK) == 0
    if graded["mode"] == "rlimits":  # the uids the reader reported
        uids = {int(part.split()[0]) for part in graded["proc"].stdout.split("uid=")[1:]}
        assert uids and _processes_of(uids) == []


def test_the_warning_names_the_mode_in_force(graded):
    warnings = [ln for ln in graded["proc"].stderr.splitlines() if "warning" in ln]
    isolations = {d["isolation"] for d in _docs(graded).values()}
    if graded["mode"].startswith("rlimits"):
        assert any("isolation is rlimits (chosen with --isolation rlimits)" in w for w in warnings), warnings
    else:
        assert not any("rlimits" in ln for ln in warnings), warnings
        assert all(i.startswith("isolated by") for i in isolations), isolations
