"""The cgroup v2 path of the resource box (mslab/grading/box.py) on a fake cgroup tree.

Machines with cgroup v1 (or a v2 mount without controllers) never take the v2 path, so
these tests run it against a folder laid out like a cgroup v2 hierarchy: they check what
the grader writes (controllers enabled, caps, CPU weight, the delegated user's leaf) and
read (CPU time, OOM kills) against the kernel's documented file formats
(Documentation/admin-guide/cgroup-v2.rst). A fake tree is not the kernel: it creates no
control files and cannot refuse, so the caps' effect is not tested here, only that the
grader asks for them. Where the kernel would remove a cgroup's control files with its
folder, the tests delete them first (``_as_kernel_rmdir``).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from mslab.grading import box
from mslab.grading.box import MAX_PROCESSES, NEEDED_V2, Box, Budget, describe, setup, teardown
from mslab.grading.owner import PREFIX, Owned

ENABLE = " ".join(f"+{c}" for c in NEEDED_V2)

MOUNTINFO = """\
22 28 0:20 / /sys rw,nosuid,nodev,noexec,relatime shared:7 - sysfs sysfs rw
30 22 0:26 / /sys/fs/cgroup rw,nosuid,nodev,noexec,relatime shared:4 - cgroup2 cgroup2 rw,nsdelegate
41 31 0:38 / /sys/fs/cgroup/unified rw,relatime - cgroup2 cgroup2 rw
50 31 0:40 / /v1/memory rw,relatime - cgroup cgroup rw,memory
51 31 0:41 / /v1/cpu,cpuacct rw,relatime - cgroup cgroup rw,cpu,cpuacct
"""


def _graders(tmp_path: Path, monkeypatch) -> tuple[str, Owned]:
    """A killed grader's folder (its lock free) and a live one's (locked), in a private temp folder."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    dead = tmp / f"{PREFIX}0123456789abcdef"
    dead.mkdir()
    (dead / ".owner").write_text("")  # nobody holds its lock: the grader was killed
    return dead.name, Owned()


def _cgroup(path: Path, controllers: str = "cpuset cpu io memory pids") -> Path:
    path.mkdir(parents=True, exist_ok=True)
    (path / "cgroup.controllers").write_text(controllers + "\n")
    (path / "cgroup.subtree_control").write_text("")
    return path


def _as_kernel_rmdir(path: Path) -> None:
    """Delete the control files of a fake cgroup (the kernel removes them with its folder)."""
    for f in path.iterdir():
        if f.is_file():
            f.unlink()


def test_mounts_and_own_cgroup_are_read_from_the_kernels_tables(tmp_path):
    info = tmp_path / "mountinfo"
    info.write_text(MOUNTINFO)
    v2, v1 = box._mounts(str(info))
    assert v2 == "/sys/fs/cgroup"  # the first cgroup2 mount
    assert v1 == {"memory": "/v1/memory", "cpu": "/v1/cpu,cpuacct", "cpuacct": "/v1/cpu,cpuacct"}
    table = tmp_path / "cgroup"
    table.write_text("4:memory:/grading\n1:cpu,cpuacct:/\n0::/user.slice/user-1000.slice/run-r1.scope\n")
    assert box._own("", str(table)) == "/user.slice/user-1000.slice/run-r1.scope"
    assert box._own("cpuacct", str(table)) == "/"
    assert box._own("memory", str(table)) == "/grading"
    with pytest.raises(OSError):
        box._own("pids", str(table))


@pytest.fixture
def root_grader(tmp_path, monkeypatch):
    """A fake v2 hierarchy, the grader as root, one stale and one live grading's cgroups."""
    root = _cgroup(tmp_path / "cgroup2")
    dead, live_owner = _graders(tmp_path, monkeypatch)
    stale = root / dead
    (stale / "sb-0123456789ab").mkdir(parents=True)
    live = root / live_owner.name
    live.mkdir()
    legacy = root / f"{PREFIX}{os.getppid()}"  # no folder to test: left alone
    legacy.mkdir()
    monkeypatch.setattr(box.os, "geteuid", lambda: 0)
    monkeypatch.setattr(box, "_mounts", lambda: (str(root), {}))
    config, why = setup(jobs=3, name=f"{PREFIX}me")
    assert why == ""
    assert legacy.is_dir()
    yield root, config, stale, live
    live_owner.close()


def test_v2_setup_as_root_enables_the_controllers_and_weights_the_grading(root_grader):
    root, config, stale, live = root_grader
    parent = root / f"{PREFIX}me"
    assert config == {"version": 2, "dirs": {"": str(parent)}}
    assert (root / "cgroup.subtree_control").read_text() == ENABLE
    assert (parent / "cgroup.subtree_control").read_text() == ENABLE
    assert (parent / "cpu.weight").read_text() == "300"  # 100 per runner
    assert not stale.exists()  # a killed grader's cgroups are removed
    assert live.is_dir()  # a running grader's are not
    assert describe(config, 256).startswith("cgroup v2 per sandbox: at most 64 processes, 256 MB")


def test_v2_box_caps_meters_and_kills_its_sandbox(root_grader):
    _, config, _, _ = root_grader
    sandbox = Box(config, memory_mb=256)
    (cg,) = sandbox.dirs.values()
    assert cg.parent == Path(config["dirs"][""])
    assert (cg / "pids.max").read_text() == str(MAX_PROCESSES)
    assert (cg / "memory.max").read_text() == str(256 * 1024 * 1024)
    assert (cg / "cpu.weight").read_text() == "100"  # an equal share among the boxes
    assert not (cg / "memory.swap.max").exists()  # written only where the kernel has swap control

    sandbox.enter()
    assert (cg / "cgroup.procs").read_text() == str(os.getpid())

    # CPU time of the whole box from cpu.stat; a test's CPU limit counts from its start
    (cg / "cpu.stat").write_text("usage_usec 1500000\nuser_usec 1000000\nsystem_usec 500000\n")
    assert sandbox.cpu_seconds() == 1.5
    budget = Budget(sandbox, 0.5)
    (cg / "cpu.stat").write_text("usage_usec 1900000\nuser_usec 1300000\nsystem_usec 600000\n")
    assert budget.exceeded() is None
    (cg / "cpu.stat").write_text("usage_usec 2000001\nuser_usec 1400001\nsystem_usec 600000\n")
    assert budget.exceeded() == "cpu"

    assert sandbox.oom_kills() == 0  # no memory.events yet
    (cg / "memory.events").write_text("low 0\nhigh 0\nmax 7\noom 2\noom_kill 1\noom_group_kill 0\n")
    assert sandbox.oom_kills() == 1

    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    try:
        (cg / "cgroup.procs").write_text(f"{sleeper.pid}\n")
        (cg / "cgroup.kill").write_text("0")
        sandbox.kill()
        assert (cg / "cgroup.kill").read_text() == "1"
        assert sleeper.wait(timeout=60) == -signal.SIGKILL  # and every pid listed is killed
    finally:
        sleeper.kill()
        sleeper.wait()

    _as_kernel_rmdir(cg)
    sandbox.close()
    assert not cg.exists()
    _as_kernel_rmdir(Path(config["dirs"][""]))
    teardown(config)
    assert not Path(config["dirs"][""]).exists()


def test_v2_setup_for_a_delegated_user_moves_the_grader_into_a_leaf(tmp_path, monkeypatch):
    root = tmp_path / "cgroup2"
    scope = _cgroup(root / "user.slice" / "run-r1.scope", "cpu memory pids")
    dead, live_owner = _graders(tmp_path, monkeypatch)
    stale_leaf = scope / f"{dead}-grader"
    stale_leaf.mkdir()
    live_leaf = scope / f"{live_owner.name}-grader"
    live_leaf.mkdir()
    monkeypatch.setattr(box.os, "geteuid", lambda: 1000)
    monkeypatch.setattr(box, "_mounts", lambda: (str(root), {}))
    monkeypatch.setattr(box, "_own", lambda hierarchy: "/user.slice/run-r1.scope")
    config, why = setup(jobs=2, name=f"{PREFIX}me")
    assert why == ""
    leaf = scope / f"{PREFIX}me-grader"
    assert (leaf / "cgroup.procs").read_text() == "0"  # "0": the writing process itself
    assert (scope / "cgroup.subtree_control").read_text() == ENABLE
    assert config == {"version": 2, "dirs": {"": str(scope / f"{PREFIX}me")}}
    assert (scope / f"{PREFIX}me" / "cpu.weight").read_text() == "200"
    assert not stale_leaf.exists()  # a killed grader's leaf is removed by the next grading
    assert live_leaf.is_dir()  # a live one's, whatever its PID namespace, is not
    live_owner.close()
    assert not (root / "cgroup.subtree_control").exists()  # nothing written above the delegation


def test_v2_setup_refuses_without_delegated_controllers(tmp_path, monkeypatch):
    root = tmp_path / "cgroup2"
    scope = _cgroup(root / "user.slice" / "run-r1.scope", "memory pids")
    monkeypatch.setattr(box.os, "geteuid", lambda: 1000)
    monkeypatch.setattr(box, "_mounts", lambda: (str(root), {}))
    monkeypatch.setattr(box, "_own", lambda hierarchy: "/user.slice/run-r1.scope")
    config, why = setup(jobs=2)
    assert config is None
    assert why == "cgroup v2: controllers cpu are not delegated to this user"
    assert sorted(p.name for p in scope.iterdir()) == ["cgroup.controllers", "cgroup.subtree_control"]
