"""A resource box per sandbox: a cgroup holding its whole process tree, else /proc as a meter.

The grader sets up one parent cgroup per grading (:func:`setup`), the runner puts every
sandbox into a child of it before the student's code starts (:class:`Box`): the whole
sandbox, however many processes it forks and in whatever session, shares one process
cap (``pids.max``), one memory cap (``memory.max``) and one CPU weight, and its CPU time
is read from the cgroup. Where no cgroup can be made (no delegation for a non-root user,
no controllers), the box only *meters*: it sums the CPU time of the sandbox's process
tree from ``/proc`` (in the namespace modes every process of the sandbox descends from
the process the runner started), and the limits stay per process (``setrlimit``).

cgroup v2 (``pids``, ``memory``, ``cpu`` enabled): as root under the hierarchy's root;
as another user inside its own cgroup when that is delegated to it (e.g. ``systemd-run
--user --scope -p Delegate=yes mslab grade ...``): the grader moves itself into a leaf
and makes the boxes its siblings (a leaf cannot be removed by the process inside it: the
next grading removes those of graders that have ended, :mod:`mslab.grading.owner`).
cgroup v1 (hybrid machines, root only): ``pids``, ``memory``, ``cpu`` and ``cpuacct`` hierarchies.

A test's CPU-time limit on a box, with its wall-clock backstop, is a :class:`Budget`.
"""

from __future__ import annotations

import os
import secrets
import signal
import tempfile
import time
from pathlib import Path

from mslab.grading.owner import PREFIX, is_abandoned

#: the wall-clock backstop of a CPU-time limit L is WALL_FACTOR * L + WALL_SLACK seconds
WALL_FACTOR, WALL_SLACK = 5.0, 10.0
#: seconds between checks of the sandbox's CPU time (reading a cgroup / walking /proc)
POLL_CGROUP, POLL_PROC = 0.05, 0.2

#: the controllers a box needs, by cgroup version
NEEDED_V2 = ("pids", "memory", "cpu")
NEEDED_V1 = ("pids", "memory", "cpu", "cpuacct")
#: processes a whole sandbox may have at once
MAX_PROCESSES = 64


def _write(path: str | Path, text: str) -> None:
    with open(path, "w") as fh:
        fh.write(text)


def _mounts(mountinfo: str = "/proc/self/mountinfo") -> tuple[str | None, dict[str, str]]:
    """Return the cgroup v2 mount point, and each v1 controller's mount point."""
    v2, v1 = None, {}
    with open(mountinfo) as fh:
        for line in fh:
            pre, _, post = line.partition(" - ")
            fstype, _, opts = (post.split() + ["", "", ""])[:3]
            point = pre.split()[4]
            if fstype == "cgroup2" and v2 is None:
                v2 = point
            elif fstype == "cgroup":
                for opt in opts.split(","):
                    if opt in NEEDED_V1:
                        v1.setdefault(opt, point)
    return v2, v1


def _own(hierarchy: str, table: str = "/proc/self/cgroup") -> str:
    """Return the grader's cgroup path in one hierarchy (``""`` for v2, a controller name for v1)."""
    with open(table) as fh:
        for line in fh:
            _, names, path = line.rstrip("\n").split(":", 2)
            if (hierarchy == "" and names == "") or hierarchy in names.split(","):
                return path
    raise OSError(f"not in a {hierarchy or 'v2'} cgroup")


def _clean_stale(parent: Path) -> None:
    """Remove the parent cgroups of graders that have ended (their folder's lock is free).

    A cgroup ``mslab-grade-<token>`` (or ``...-grader``, a delegated grader's leaf) belongs
    to the grading whose folder ``<tmp>/mslab-grade-<token>`` is locked
    (:mod:`mslab.grading.owner`); without that folder to test it is left alone (a grader
    sharing the cgroup tree but not the temporary folder cannot be proven gone).
    """
    for folder in parent.glob(f"{PREFIX}*"):
        name = folder.name.removesuffix("-grader")
        if not is_abandoned(Path(tempfile.gettempdir()) / name):
            continue
        for child in folder.iterdir():
            if child.is_dir():
                _rmdir(child)
        _rmdir(folder)


def _rmdir(path: Path, tries: int = 50) -> bool:
    for _ in range(tries):
        try:
            path.rmdir()
            return True
        except FileNotFoundError:
            return True
        except OSError:
            _kill_procs(path)
            time.sleep(0.02)
    return False


def _kill_procs(path: Path) -> None:
    try:
        pids = [int(p) for p in (path / "cgroup.procs").read_text().split()]
    except OSError:
        return
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass


def _setup_v2(mount: str, jobs: int, name: str) -> dict:
    root = Path(mount)
    if os.geteuid() == 0:
        base = root
        _write(base / "cgroup.subtree_control", " ".join(f"+{c}" for c in NEEDED_V2))
    else:  # a delegated cgroup of our own: move into a leaf, the boxes become its siblings
        base = root / _own("").lstrip("/")
        missing = set(NEEDED_V2) - set((base / "cgroup.controllers").read_text().split())
        if missing:
            raise OSError(f"controllers {', '.join(sorted(missing))} are not delegated to this user")
        leaf = base / f"{name}-grader"
        leaf.mkdir(exist_ok=True)
        _write(leaf / "cgroup.procs", "0")
        _write(base / "cgroup.subtree_control", " ".join(f"+{c}" for c in NEEDED_V2))
    _clean_stale(base)
    parent = base / name
    parent.mkdir()
    _write(parent / "cgroup.subtree_control", " ".join(f"+{c}" for c in NEEDED_V2))
    _write(parent / "cpu.weight", str(min(10_000, 100 * jobs)))
    return {"version": 2, "dirs": {"": str(parent)}}


def _setup_v1(mounts: dict[str, str], jobs: int, name: str) -> dict:
    if os.geteuid() != 0:
        raise OSError("cgroup v1 hierarchies are not delegated to users")
    missing = set(NEEDED_V1) - set(mounts)
    if missing:
        raise OSError(f"no v1 hierarchy for {', '.join(sorted(missing))}")
    dirs = {}
    for ctrl in NEEDED_V1:
        base = Path(mounts[ctrl]) / _own(ctrl).lstrip("/")
        _clean_stale(base)
        parent = base / name
        parent.mkdir(exist_ok=True)
        dirs[ctrl] = str(parent)
    _write(Path(dirs["cpu"]) / "cpu.shares", str(1024 * jobs))
    return {"version": 1, "dirs": dirs}


def setup(jobs: int, name: str | None = None) -> tuple[dict | None, str]:
    """Make the grading's parent cgroup; ``(config for the runners, "")`` or ``(None, why not)``.

    ``name`` is the grading's owned folder's name (:class:`mslab.grading.owner.Owned`),
    which stale clean-up tests; default ``mslab-grade-<pid>`` (never found abandoned).
    """
    name = name or f"{PREFIX}{os.getpid()}"
    try:
        v2, v1 = _mounts()
    except OSError as err:
        return None, f"cannot read the mounts ({err.strerror})"
    reasons = []
    if v2 is not None:
        try:
            return _setup_v2(v2, jobs, name), ""
        except OSError as err:
            reasons.append(f"cgroup v2: {err.strerror or err}")
    if v1:
        try:
            return _setup_v1(v1, jobs, name), ""
        except OSError as err:
            reasons.append(f"cgroup v1: {err.strerror or err}")
    return None, "; ".join(reasons) or "no cgroup file system"


def teardown(config: dict | None) -> None:
    """Remove the grading's parent cgroup (and any box a killed runner left)."""
    if not config:
        return
    for parent in config["dirs"].values():
        path = Path(parent)
        if path.is_dir():
            for child in path.iterdir():
                if child.is_dir():
                    _rmdir(child)
            _rmdir(path)


def describe(config: dict | None, memory_mb: int) -> str:
    """One phrase for the report: the caps every sandbox had."""
    if not config:
        return "no cgroup: limits per process only"
    return (f"cgroup v{config['version']} per sandbox: at most {MAX_PROCESSES} processes, "
            f"{memory_mb} MB together, an equal CPU share")


class Box:
    """One sandbox's cgroup (``config`` from :func:`setup`), or a /proc meter when ``config`` is None."""

    def __init__(self, config: dict | None, memory_mb: int):
        self.config = config
        self.dirs: dict[str, Path] = {}
        self.root_pid: int | None = None
        if config:
            name = f"sb-{secrets.token_hex(6)}"
            for ctrl, parent in config["dirs"].items():
                path = Path(parent) / name
                path.mkdir()
                self.dirs[ctrl] = path
            limit = memory_mb * 1024 * 1024
            if config["version"] == 2:
                d = self.dirs[""]
                _write(d / "pids.max", str(MAX_PROCESSES))
                _write(d / "memory.max", str(limit))
                if (d / "memory.swap.max").exists():
                    _write(d / "memory.swap.max", "0")
                _write(d / "cpu.weight", "100")
            else:
                _write(self.dirs["pids"] / "pids.max", str(MAX_PROCESSES))
                _write(self.dirs["memory"] / "memory.limit_in_bytes", str(limit))
                _write(self.dirs["cpu"] / "cpu.shares", "1024")

    def enter(self) -> None:
        """Move the calling process into the box (in the child, between fork and exec)."""
        for path in self.dirs.values():
            _write(path / "cgroup.procs", str(os.getpid()))

    def started(self, pid: int) -> None:
        """Remember the process the runner started (the root of the sandbox's tree)."""
        self.root_pid = pid

    def cpu_seconds(self) -> float:
        """CPU time used so far by every process of the sandbox (seconds)."""
        try:
            if self.config and self.config["version"] == 2:
                for line in (self.dirs[""] / "cpu.stat").read_text().splitlines():
                    if line.startswith("usage_usec "):
                        return int(line.split()[1]) / 1e6
            elif self.config:
                return int((self.dirs["cpuacct"] / "cpuacct.usage").read_text()) / 1e9
        except (OSError, ValueError):
            pass
        return _tree_cpu(self.root_pid) if self.root_pid else 0.0

    def oom_kills(self) -> int:
        """How often the kernel killed a process of the box for memory (0 without a cgroup)."""
        if not self.config:
            return 0
        name = "memory.events" if self.config["version"] == 2 else "memory.oom_control"
        path = self.dirs["" if self.config["version"] == 2 else "memory"] / name
        try:
            for line in path.read_text().splitlines():
                if line.startswith("oom_kill "):
                    return int(line.split()[1])
        except (OSError, ValueError):
            pass
        return 0

    def kill(self) -> None:
        """Kill every process in the box."""
        if self.config and self.config["version"] == 2 and (self.dirs[""] / "cgroup.kill").exists():
            try:
                _write(self.dirs[""] / "cgroup.kill", "1")
            except OSError:
                pass
        for path in self.dirs.values():
            _kill_procs(path)

    def close(self) -> None:
        """Kill what is left and remove the box."""
        self.kill()
        for path in self.dirs.values():
            _rmdir(path)
        self.dirs = {}


def wall_backstop(cpu_limit: float) -> float:
    """Return the wall-clock limit behind a CPU-time limit: generous, so others' load never hits it."""
    return WALL_FACTOR * cpu_limit + WALL_SLACK


class Budget:
    """A CPU-time limit on the whole sandbox, from now, with a wall-clock backstop."""

    def __init__(self, box: Box, cpu_limit: float):
        self.box, self.cpu_limit = box, float(cpu_limit)
        self.cpu0 = box.cpu_seconds()
        self.measured = time.monotonic()
        self.wall_end = self.measured + wall_backstop(cpu_limit)
        self.spent = 0.0

    def exceeded(self, every: float = 0.0) -> str | None:
        """``"cpu"`` or ``"wall"`` once a limit is hit, else None (measured by the runner itself).

        The sandbox's CPU time is measured again only when ``every`` seconds of wall-clock time
        have passed since the last measurement (0: always). A reply within ``every`` then costs
        no measurement (a cgroup file read, or without a cgroup a walk of ``/proc``: 1-5 ms a
        call on a busy machine, which made a test of many fast calls ten times slower); the CPU
        time used since the last measurement, at most ``every`` seconds per process of the
        sandbox, is counted at the next one, so a limit is found as late as it is while one
        long call is polled (:data:`POLL_CGROUP`, :data:`POLL_PROC`).
        """
        now = time.monotonic()
        if now - self.measured >= every:
            self.spent, self.measured = self.box.cpu_seconds() - self.cpu0, now
        if self.spent > self.cpu_limit:
            return "cpu"
        return "wall" if now >= self.wall_end else None


def _tree_cpu(root: int) -> float:
    """CPU seconds of ``root`` and its descendants (and the children they reaped), from /proc."""
    children: dict[int, list[int]] = {}
    ticks: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as fh:
                fields = fh.read().rsplit(b")", 1)[1].split()
        except OSError:
            continue
        pid = int(entry)
        children.setdefault(int(fields[1]), []).append(pid)  # fields: state ppid ... (after the name)
        ticks[pid] = sum(int(f) for f in fields[11:15])  # utime stime cutime cstime
    total, todo = 0, [root]
    while todo:
        pid = todo.pop()
        total += ticks.get(pid, 0)
        todo.extend(children.get(pid, ()))
    return total / os.sysconf("SC_CLK_TCK")


def user_process_cap(extra: int) -> int:
    """Return an ``RLIMIT_NPROC`` that lets this user start ``extra`` more processes than it has now.

    Without a cgroup and as a user (not root) no limit counts one sandbox's processes only:
    ``RLIMIT_NPROC`` counts all processes of the user. Set to its count at the sandbox's
    start plus ``extra``, it stops a fork bomb within ``extra`` processes; sandboxes side by
    side share that headroom (one's bomb can make a classmate's fork fail until the bomb's
    sandbox is killed at its limit), and the grader's own processes count too.
    """
    uid, count = os.getuid(), 0
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                if os.stat(f"/proc/{entry}").st_uid == uid:
                    count += 1
            except OSError:
                continue
    return count + extra
