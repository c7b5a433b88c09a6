"""Namespaces without bubblewrap: ``python -I -S jail.py CONFIG`` starts the sandbox isolated.

Standard library only (it runs before anything of mslab is importable in the sandbox).
``CONFIG`` is JSON: ``mounts`` (as in :class:`mslab.grading.isolation.Mount`), ``uid``
(the fresh uid when run as root, else null), ``source_fd`` (the student's file) and
``argv`` (the sandbox command). The launcher

1. unshares mount, PID, network, IPC and UTS namespaces (as a non-root user also a user
   namespace mapping its own uid), and forks: the child is PID 1 of the new PID namespace,
   so everything the student starts dies with it;
2. builds a root on a tmpfs (read-only binds, masks, ``/work`` holding the student's
   file, ``/tmp``, ``/dev`` nodes, ``/proc``), ``pivot_root`` into it, drops the old root;
3. as root becomes the fresh uid, then enters a user namespace of its own; no new
   privileges; execs the sandbox. The parent waits and exits with the child's status.
"""

import ctypes
import json
import os
import signal
import sys

CLONE_NEWNS, CLONE_NEWUTS, CLONE_NEWIPC = 0x00020000, 0x04000000, 0x08000000
CLONE_NEWUSER, CLONE_NEWPID, CLONE_NEWNET = 0x10000000, 0x20000000, 0x40000000
MS_RDONLY, MS_NOSUID, MS_NODEV, MS_NOEXEC, MS_REMOUNT = 1, 2, 4, 8, 32
MS_BIND, MS_REC, MS_PRIVATE = 4096, 16384, 1 << 18
MNT_DETACH, SYS_PIVOT_ROOT = 2, 155
PR_SET_PDEATHSIG, PR_SET_NO_NEW_PRIVS = 1, 38
#: statvfs flags a bind remount must keep (locked in a user namespace) -> mount flags
KEEP = {1: MS_RDONLY, 2: MS_NOSUID, 4: MS_NODEV, 8: MS_NOEXEC, 1024: 1024, 2048: 2048, 4096: 1 << 21}

libc = ctypes.CDLL(None, use_errno=True)


def check(result: int, what: str) -> None:
    """Raise OSError naming ``what`` and errno's text when a libc call returned non-zero."""
    if result != 0:
        err = ctypes.get_errno()
        raise OSError(err, f"{what}: {os.strerror(err)}")


def mount(src: str | None, dst: str, fstype: str | None, flags: int, data: str | None = None) -> None:
    """Call mount(2) (``None`` passes a null pointer)."""
    enc = [None if s is None else s.encode() for s in (src, dst, fstype, data)]
    check(libc.mount(enc[0], enc[1], enc[2], ctypes.c_ulong(flags), enc[3]), f"mount {dst}")


def bind(src: str, dst: str, readonly: bool = True) -> None:
    """Bind ``src`` read-only (or writable) at ``dst``, keeping the flags a user namespace locks."""
    if os.path.isdir(src):
        os.makedirs(dst, exist_ok=True)
    else:
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        if not os.path.exists(dst):
            open(dst, "wb").close()
    mount(src, dst, None, MS_BIND | MS_REC)
    kept = 0
    flag = os.statvfs(dst).f_flag
    for bit, ms in KEEP.items():
        if flag & bit:
            kept |= ms
    mount(None, dst, None, MS_REMOUNT | MS_BIND | (MS_RDONLY if readonly else MS_NODEV) | MS_NOSUID | kept)


def write(path: str, text: str) -> None:
    """Write ``text`` to the file ``path``."""
    with open(path, "w") as fh:
        fh.write(text)


def build_root(root: str, config: dict, source: bytes) -> None:
    """Build the sandbox's root on a tmpfs at ``root`` (mounts, the student's file, /dev, /proc)."""
    mount("tmpfs", root, "tmpfs", MS_NOSUID | MS_NODEV, "size=1m,mode=0755")
    for m in config["mounts"]:
        dst = root + m["dst"]
        if m["kind"] == "dir":
            os.makedirs(dst, exist_ok=True)
            os.chmod(dst, m["mode"])
        elif m["kind"] in ("ro", "rw"):
            bind(m["src"], dst, readonly=m["kind"] == "ro")
        elif m["kind"] == "symlink":
            os.symlink(m["src"], dst)
        elif m["kind"] == "tmpfs":
            os.makedirs(dst, exist_ok=True)
            mount("tmpfs", dst, "tmpfs", MS_NOSUID | MS_NODEV, f"size={m['size']},mode={m['mode']:o}")
    module = root + "/work/" + os.path.basename(config.get("module") or "module.py")
    with open(module, "wb") as fh:
        fh.write(source)
    os.chmod(module, 0o444)
    os.makedirs(root + "/dev", exist_ok=True)
    for name in ("null", "zero", "random", "urandom"):
        target = root + "/dev/" + name
        open(target, "wb").close()
        mount("/dev/" + name, target, None, MS_BIND)
    os.makedirs(root + "/proc", exist_ok=True)
    try:
        mount("proc", root + "/proc", "proc", MS_NOSUID | MS_NODEV | MS_NOEXEC)
    except OSError:
        pass  # a user namespace may not mount proc under a masked /proc: the sandbox runs without


def enter_root(root: str) -> None:
    """Make ``root`` the root (``pivot_root``), drop the old one, remount it read-only."""
    os.chdir(root)
    os.mkdir("oldroot")
    check(libc.syscall(SYS_PIVOT_ROOT, b".", b"oldroot"), "pivot_root")
    os.chdir("/")
    check(libc.umount2(b"/oldroot", MNT_DETACH), "umount old root")
    os.rmdir("/oldroot")
    mount(None, "/", None, MS_REMOUNT | MS_BIND | MS_RDONLY | MS_NOSUID | MS_NODEV)


def child(config: dict, source: bytes, root: str) -> None:
    """Be PID 1 of the new namespace: build and enter the root, drop privileges, exec the sandbox."""
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    mount(None, "/", None, MS_REC | MS_PRIVATE)
    build_root(root, config, source)
    enter_root(root)
    uid = config["uid"]
    if uid is not None:
        os.setgroups([])
        os.setgid(uid)
        os.setuid(uid)
        libc.unshare(CLONE_NEWUSER)  # unprivileged now: a user namespace of its own, if allowed
    libc.prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0)
    os.chdir("/work")
    argv = config["argv"]
    os.execve(argv[0], argv, os.environ)


def staging_dir(config: dict) -> str:
    """Pick where the new root is built: an existing folder that holds none of the bound sources.

    The tmpfs mounted there hides what it covers, so a grader whose checkout or venv lives
    under ``/tmp`` (a fresh clone, CI) must not have its root staged on ``/tmp``.
    """
    sources = [m["src"] for m in config["mounts"] if m.get("src", "").startswith("/")]
    for candidate in ("/mnt", "/media", "/srv", "/tmp", "/var/tmp", "/opt"):
        if os.path.isdir(candidate) and not any(src == candidate or src.startswith(candidate + "/")
                                                for src in sources):
            return candidate
    raise OSError("no folder to stage the sandbox's root in (every candidate holds a bound source)")


def main() -> None:
    """Unshare the namespaces, fork the child and exit as it exits (``CONFIG`` is ``sys.argv[1]``)."""
    config = json.loads(sys.argv[1])
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    with os.fdopen(config["source_fd"], "rb") as fh:
        source = fh.read()
    root_user = os.geteuid() == 0
    uid, gid = os.getuid(), os.getgid()
    flags = CLONE_NEWNS | CLONE_NEWPID | CLONE_NEWNET | CLONE_NEWIPC | CLONE_NEWUTS
    check(libc.unshare(flags if root_user else flags | CLONE_NEWUSER), "unshare")
    if not root_user:
        write("/proc/self/setgroups", "deny")
        write("/proc/self/uid_map", f"{uid} {uid} 1")
        write("/proc/self/gid_map", f"{gid} {gid} 1")
    root = staging_dir(config)
    pid = os.fork()
    if pid == 0:
        try:
            child(config, source, root)
        except BaseException as err:  # noqa: BLE001 - one line for the runner, then out
            os.write(2, f"jail: {err}\n".encode())
        os._exit(127)
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):  # die the same way, so the runner can name the signal
        sig = os.WTERMSIG(status)
        signal.signal(sig, signal.SIG_DFL)
        os.kill(os.getpid(), sig)
    os._exit(os.waitstatus_to_exitcode(status) % 256)


if __name__ == "__main__":
    main()
