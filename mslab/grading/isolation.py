"""How the sandbox is isolated from the grader: the strongest the machine offers.

Three modes, tried in this order:

``bwrap``
    bubblewrap: new PID, mount, network, IPC and UTS namespaces (and a user namespace);
    as root the student runs as a fresh unprivileged uid (``setpriv``), otherwise as the
    grader's uid mapped into a user namespace.
``namespaces``
    the same built from Python (:mod:`mslab.grading.jail`, ``unshare`` + ``pivot_root``).
``rlimits``
    no namespaces: resource limits only, in the grader's file system (a warning says so).
    As root (a platform's container, where Docker's seccomp profile blocks user
    namespaces) each sandbox runs as a fresh throwaway uid and gid (no groups, no
    capabilities, no new privileges, at most 64 processes of that uid, all killed when
    the sandbox ends) on a root-owned copy of what it may read (:func:`rlimits_as_uid`),
    while the grader closes the instructor's tree and the submissions to other users
    (mode 0700 while grading). Anything else on the machine that other users may read,
    the student may read too.

In both namespace modes the student's process sees a read-only view of the interpreter,
the standard library and numpy only (no ``mslab``, no site-packages, no source tree, no
other submission), a private ``/tmp`` and ``/work`` (small tmpfs holding its file), a
``/proc`` of its own PID namespace and no network; everything it starts dies with it.
"""

from __future__ import annotations

import contextlib
import glob
import json
import os
import secrets
import shutil
import signal
import stat
import subprocess
import sys
import sysconfig
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: the trusted files the sandbox runs (imported by file path, without mslab)
SANDBOX_FILES = ("sandbox.py", "wire.py", "problems.py", "unzip.py")
#: the trusted acceleration of the step exercises: a spring-force implementation, so a sandbox
#: has it only where the tests hand the student a problem (never for exercise 01's forces)
PROBLEMS = "problems.py"


def sandbox_files(problems: bool = True) -> tuple[str, ...]:
    """Return the trusted files a sandbox gets: all of them, or without the problems' acceleration."""
    return SANDBOX_FILES if problems else tuple(f for f in SANDBOX_FILES if f != PROBLEMS)


JAIL = HERE / "jail.py"
MODES = ("bwrap", "namespaces", "rlimits")
#: size of the student's /work and /tmp (bytes)
TMPFS_SIZE = 64 * 1024 * 1024
#: the student's uid when the grader is root: a fresh one per sandbox, owning no file
UID_BASE, UID_SPAN = 2_000_000, 1_000_000

DESCRIPTION = {
    "bwrap": "isolated by bubblewrap (user, PID, mount, network, IPC namespaces)",
    "namespaces": "isolated by Linux namespaces (user, PID, mount, network, IPC; no bwrap)",
    "rlimits": "NOT isolated: resource limits only, student code runs as the grader's user "
               "in the grader's file system",
}


@dataclass
class Mount:
    """One entry of the sandbox's file system: ``ro`` or ``rw`` bind, ``dir``, ``tmpfs`` or ``symlink``."""

    kind: str
    dst: str
    src: str = ""
    size: int = 0
    mode: int = 0o755


@dataclass
class Plan:
    """The sandbox's file system and the command it runs (paths inside the sandbox)."""

    mounts: list[Mount] = field(default_factory=list)
    python: str = ""


def _python_files() -> tuple[str, list[str]]:
    """Return the real interpreter and the folders it needs (its prefix's lib folders)."""
    exe = os.path.realpath(sys.executable)
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    stdlib = sysconfig.get_paths(vars={"base": sys.base_prefix, "platbase": sys.base_prefix})["stdlib"]
    folders = [os.path.realpath(p) for p in (libdir, stdlib) if p and os.path.isdir(p)]
    return exe, folders


def _site_folders(roots: list[str]) -> list[str]:
    """site-/dist-packages folders under the bound trees (hidden behind empty tmpfs)."""
    found = []
    for root in roots:
        for pattern in ("site-packages", "dist-packages", "python3*/site-packages", "python3*/dist-packages",
                        "lib/python3*/site-packages", "lib/python3*/dist-packages", "local/lib/python3*"):
            found.extend(p for p in glob.glob(os.path.join(root, pattern)) if os.path.isdir(p))
    return sorted(set(found))


def _outermost(paths: list[str]) -> list[str]:
    """``paths`` without those inside another one of them."""
    out: list[str] = []
    for p in sorted(set(paths), key=len):
        if not any(p == q or p.startswith(q.rstrip("/") + "/") for q in out):
            out.append(p)
    return sorted(out)


def plan(problems: bool = True) -> Plan:
    """Return the mounts of a sandbox (the same for every student; computed by the runner).

    ``problems=False``: without ``problems.py`` (:func:`sandbox_files`).
    """
    import numpy

    exe, folders = _python_files()
    mounts: list[Mount] = []
    dirs: set[str] = set()

    def parents(path: str) -> None:
        parent = os.path.dirname(path)
        while parent not in ("/", ""):
            dirs.add(parent)
            parent = os.path.dirname(parent)

    for top in ("/usr", "/lib", "/lib64", "/lib32", "/bin", "/sbin"):
        if os.path.islink(top):
            mounts.append(Mount("symlink", top, os.readlink(top)))
        elif os.path.isdir(top):
            mounts.append(Mount("ro", top, top))
    if os.path.isfile("/etc/ld.so.cache"):
        mounts.append(Mount("ro", "/etc/ld.so.cache", "/etc/ld.so.cache"))
        parents("/etc/ld.so.cache")
    system = ("/usr/", "/lib", "/bin", "/sbin")
    if not exe.startswith(system):
        mounts.append(Mount("ro", exe, exe))
        parents(exe)
    for folder in _outermost(folders):
        if not folder.startswith(system):
            mounts.append(Mount("ro", folder, folder))
            parents(folder)
    masked = _site_folders([f for f in folders] + ["/usr/lib", "/usr/local/lib", "/usr"])
    mounts += [Mount("tmpfs", p, size=4096, mode=0o555) for p in _outermost(masked)]
    numpy_dir = os.path.dirname(os.path.realpath(numpy.__file__))
    mounts.append(Mount("ro", "/grader/numpy", numpy_dir))
    libs = numpy_dir + ".libs"
    if os.path.isdir(libs):
        mounts.append(Mount("ro", "/grader/numpy.libs", libs))
    for name in sandbox_files(problems):
        mounts.append(Mount("ro", f"/grader/{name}", str(HERE / name)))
    dirs.add("/grader")
    mounts.append(Mount("tmpfs", "/work", size=TMPFS_SIZE, mode=0o1777))
    mounts.append(Mount("tmpfs", "/tmp", size=TMPFS_SIZE, mode=0o1777))
    ordered = [Mount("dir", d, mode=0o755) for d in sorted(dirs, key=len)]
    return Plan(ordered + mounts, exe)


def sandbox_argv(python: str, module: str = "module.py") -> list[str]:
    """Return the sandbox command inside the namespaces (``-S``: no site, numpy from /grader)."""
    return [python, "-E", "-s", "-S", "/grader/sandbox.py", f"/work/{module}"]


def new_uid() -> int | None:
    """Return a fresh unprivileged uid for one sandbox when the grader is root, else None."""
    return UID_BASE + secrets.randbelow(UID_SPAN) if os.geteuid() == 0 else None


def bwrap_command(p: Plan, source_fd: int, uid: int | None, argv: list[str] | None = None,
                  module: str = "module.py") -> list[str]:
    """Return the bubblewrap command line running the sandbox (the student's file from ``source_fd``)."""
    args = [shutil.which("bwrap") or "bwrap", "--unshare-pid", "--unshare-net", "--unshare-ipc",
            "--unshare-uts", "--unshare-cgroup-try", "--die-with-parent", "--new-session"]
    if uid is None:
        args.append("--unshare-user")
    else:  # root: keep only what setpriv needs to become the fresh uid
        args += ["--cap-add", "CAP_SETUID", "--cap-add", "CAP_SETGID"]
    for m in p.mounts:
        if m.kind == "dir":
            args += ["--perms", f"{m.mode:04o}", "--dir", m.dst]
        elif m.kind in ("ro", "rw"):
            args += ["--ro-bind" if m.kind == "ro" else "--bind", m.src, m.dst]
        elif m.kind == "symlink":
            args += ["--symlink", m.src, m.dst]
        elif m.kind == "tmpfs":
            args += ["--perms", f"{m.mode:04o}", "--size", str(m.size), "--tmpfs", m.dst]
    args += ["--perms", "0444", "--file", str(source_fd), f"/work/{module}",
             "--proc", "/proc", "--dev", "/dev", "--remount-ro", "/", "--chdir", "/work"]
    if uid is not None:
        args += ["/usr/bin/setpriv", f"--reuid={uid}", f"--regid={uid}", "--clear-groups",
                 "--inh-caps=-all", "--bounding-set=-all", "--no-new-privs"]
        if os.path.exists("/usr/bin/unshare"):
            args += ["/usr/bin/unshare", "--user"]
    return args + (argv or sandbox_argv(p.python, module))


def jail_command(p: Plan, source_fd: int, uid: int | None, argv: list[str] | None = None,
                 module: str = "module.py") -> list[str]:
    """Return the Python namespace launcher (:mod:`mslab.grading.jail`) running the sandbox."""
    config = {"mounts": [m.__dict__ for m in p.mounts], "uid": uid, "source_fd": source_fd,
              "module": module, "argv": argv or sandbox_argv(p.python, module)}
    return [os.path.realpath(sys.executable), "-I", "-S", str(JAIL), json.dumps(config)]


def rlimit_command(module_file: Path) -> list[str]:
    """Return the old sandbox: the grader's interpreter on the student's file, limits only."""
    return [sys.executable, "-E", "-s", str(HERE / "sandbox.py"), str(module_file)]


#: environment variable naming the grading's own folder (set for the runners by the grader)
HOME_ENV = "MSLAB_GRADE_HOME"
_STAGE: Path | None = None


def _stage() -> Path:
    """Return the root-owned folder of what a sandbox run as a throwaway uid may read (one per runner).

    Mode 0711 (others may pass, not list): ``grader/`` holds the sandbox's own files
    (mode 0444) and links to numpy, ``grader-plain/`` the same without ``problems.py``; each
    sandbox gets a folder ``work-UID`` of its own.
    """
    global _STAGE
    if _STAGE is None:
        import numpy

        stage = Path(tempfile.mkdtemp(prefix="stage-", dir=os.environ.get(HOME_ENV) or None))
        os.chmod(stage, 0o711)
        numpy_dir = os.path.dirname(os.path.realpath(numpy.__file__))
        for folder, problems in (("grader", True), ("grader-plain", False)):
            grader = stage / folder
            grader.mkdir(mode=0o755)
            for name in sandbox_files(problems):
                shutil.copyfile(HERE / name, grader / name)
                os.chmod(grader / name, 0o444)
            os.symlink(numpy_dir, grader / "numpy")
            if os.path.isdir(numpy_dir + ".libs"):
                os.symlink(numpy_dir + ".libs", grader / "numpy.libs")
        _STAGE = stage
    return _STAGE


def rlimits_as_uid(module_file: Path, uid: int, problems: bool = True) -> tuple[list[str], Path]:
    """Return the command running a sandbox as ``uid`` (rlimits as root), and its own folder.

    The student's file is a root-owned read-only copy in ``work-UID`` (mode 0700, owned by
    ``uid``: its scratch space); the interpreter runs with ``-S`` (no site-packages, no
    mslab) and imports the sandbox's files and numpy from the stage.
    """
    work = _stage() / f"work-{uid}"
    work.mkdir(mode=0o700)
    os.chown(work, uid, uid)
    target = work / module_file.name
    shutil.copyfile(module_file, target)
    os.chmod(target, 0o444)
    python = os.path.realpath(sys.executable)
    grader = _stage() / ("grader" if problems else "grader-plain")
    return [python, "-E", "-s", "-S", str(grader / "sandbox.py"), str(target)], work


def unreachable_for_others() -> str:
    """Name what a throwaway uid could not reach (interpreter, standard library, numpy), or ``""``."""
    import numpy

    exe, folders = _python_files()
    for path in [exe, *folders, os.path.dirname(os.path.realpath(numpy.__file__))]:
        parts = Path(path).parts
        for k in range(2, len(parts) + 1):
            here = os.path.join(*parts[:k])
            if os.path.isdir(here) and not os.stat(here).st_mode & 0o001:
                return f"{path} (the folder {here} is closed to other users)"
    return ""


def rlimits_sandbox(module_file: Path, workdir: Path,
                    problems: bool = True) -> tuple[list[str], Path, int | None]:
    """Return the rlimits sandbox's command, folder and uid (a throwaway one as root, else None).

    As the grader's own user (no throwaway uid) the student reads what the grader reads, the
    installed mslab included: ``problems`` cannot be withheld there (README's table).
    """
    uid = new_uid()
    if uid is None:
        return rlimit_command(module_file), workdir, None
    argv, home = rlimits_as_uid(module_file, uid, problems)
    return argv, home, uid


def become(uid: int) -> None:
    """Drop to ``uid`` for good (in the child, between fork and exec): no groups, no capabilities."""
    os.setgroups([])
    os.setgid(uid)
    os.setuid(uid)


def release_uid(uid: int) -> None:
    """Kill every process of the throwaway ``uid``, remove its files and its folder.

    The processes and what the uid left in the shared writable folders (:func:`remove_files_of`)
    go from a process of that uid: the owner may unlink its files in a sticky folder, whatever
    capabilities the runner kept.
    """
    pid = os.fork()
    if pid == 0:
        try:
            become(uid)
            os.kill(-1, signal.SIGKILL)  # every process this uid may signal: its own, except this one
            remove_files_of(uid)
        finally:
            os._exit(0)
    os.waitpid(pid, 0)
    if _STAGE is not None:
        shutil.rmtree(_STAGE / f"work-{uid}", ignore_errors=True)


#: the folders every uid may write to: a sandbox's files there are removed when it ends
SHARED_WRITABLE = ("/tmp", "/var/tmp", "/dev/shm", "/run/lock", "/dev/mqueue")


def remove_files_of(uid: int, roots: tuple[str, ...] = SHARED_WRITABLE) -> None:
    """Remove every file and folder owned by ``uid`` in the world-writable folders under ``roots``.

    A throwaway uid can create files only where everyone may write: the roots and any
    world-writable folder inside them (searched, never through a symbolic link). What it owns is
    removed whole (``shutil.rmtree`` does not follow links); nothing of another uid is touched.
    """
    todo = [r for r in roots if os.path.isdir(r) and not os.path.islink(r)]
    while todo:
        try:
            entries = list(os.scandir(todo.pop()))
        except OSError:
            continue
        for entry in entries:
            try:
                st = entry.stat(follow_symlinks=False)
            except OSError:
                continue
            if st.st_uid == uid:
                if stat.S_ISDIR(st.st_mode):
                    shutil.rmtree(entry.path, ignore_errors=True)
                else:
                    with contextlib.suppress(OSError):
                        os.unlink(entry.path)
            elif stat.S_ISDIR(st.st_mode) and st.st_mode & stat.S_IWOTH:
                todo.append(entry.path)


def _probe(mode: str) -> bool:
    """Can this machine start a sandbox in ``mode``? (runs ``import numpy`` inside)."""
    if mode == "bwrap" and not shutil.which("bwrap"):
        return False
    if mode == "bwrap" and os.geteuid() == 0 and not os.path.exists("/usr/bin/setpriv"):
        return False
    p = plan()
    p.mounts = [m for m in p.mounts if not m.dst.startswith("/grader/") or "numpy" in m.dst]
    r, w = os.pipe()
    os.write(w, b"")
    os.close(w)
    build = bwrap_command if mode == "bwrap" else jail_command
    argv = build(p, r, new_uid(), [p.python, "-E", "-s", "-S", "-c",
                                   "import sys; sys.path.insert(0, '/grader'); import numpy"])
    try:
        proc = subprocess.run(argv, pass_fds=(r,), stdin=subprocess.DEVNULL, capture_output=True, timeout=60)
        return proc.returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False
    finally:
        os.close(r)


def detect(mode: str = "auto") -> str:
    """Return the isolation to use: ``mode`` if given (ValueError if unavailable), else the strongest."""
    if mode not in ("auto", *MODES):
        raise ValueError(f"unknown isolation {mode!r} (choose from auto, {', '.join(MODES)})")
    if mode == "rlimits":
        return mode
    if not sys.platform.startswith("linux"):
        if mode != "auto":
            raise ValueError(f"isolation {mode!r} needs Linux")
        return "rlimits"
    if mode != "auto":
        if not _probe(mode):
            raise ValueError(f"isolation {mode!r} is not available on this machine")
        return mode
    for candidate in ("bwrap", "namespaces"):
        if _probe(candidate):
            return candidate
    return "rlimits"
