"""A submitted ``.zip`` is unpacked inside a sandbox's limits, never in the grader (issue 35).

Planted zips, one per way a zip can hurt (a bomb, a bomb lying about its size, too many
members, ``..``/absolute/backslash names, a symbolic-link member, a member over the cap,
corrupt, truncated, encrypted, nested, a name twice, too deep, decompression that needs
more memory or CPU than the sandbox has) are unpacked with
:func:`mslab.grading.unpack.unpack_zip` in every isolation mode this machine has (by a
process like the grader, as in ``test_grading_hostile_class``): each is refused with its
reason, an honest zip gives its files, and nothing is left in the grader's folder or
its temporary folder. The grader's own reading of the unpacked folder
(:func:`mslab.grading.intake.read_tree`) is tested on planted folders too: the unpacker
that wrote them is not trusted either. The gradebook rows of hostile zips are checked in
``test_grading_classes`` (one grading of a class).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import stat
import struct
import subprocess
import sys
import tempfile
import warnings
import zipfile
from pathlib import Path

import pytest
from test_grading_hostile_class import MODES, _skip_reason
from test_grading_trust import _open_views, leftovers

from mslab.grading.intake import read_tree

ROOT = Path(__file__).resolve().parents[1]
SOURCE_TEXT = "def f(x):\n    return 2 * x\n"


def _zip(members: list[tuple[str | zipfile.ZipInfo, bytes]], method: int = zipfile.ZIP_DEFLATED) -> bytes:
    buf = io.BytesIO()
    with warnings.catch_warnings(), zipfile.ZipFile(buf, "w", method) as zf:
        warnings.simplefilter("ignore")  # a name twice is the point of one payload
        for name, data in members:
            zf.writestr(name, data)
    return buf.getvalue()


def _symlink_member() -> bytes:
    info = zipfile.ZipInfo("alice/01_x/f.py")
    info.external_attr = (stat.S_IFLNK | 0o777) << 16
    return _zip([(info, b"/etc/passwd")])


def _encrypted() -> bytes:
    """A member whose flags say encrypted (zipfile writes none: the bit is set in both headers)."""
    raw = bytearray(_zip([("alice/01_x/f.py", SOURCE_TEXT.encode())], zipfile.ZIP_STORED))
    for signature, offset in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):  # local, central: flags
        raw[raw.index(signature) + offset] |= 0x1
    return bytes(raw)


def _lying_bomb() -> bytes:
    """100 MB of zeros whose headers declare 1000 bytes (the declared total passes the cap)."""
    raw = bytearray(_zip([("alice/01_x/f.py", b"0" * 100_000_000)]))
    for signature, offset in ((b"PK\x03\x04", 22), (b"PK\x01\x02", 24)):  # local, central: file size
        at = raw.index(signature)
        struct.pack_into("<I", raw, at + offset, 1000)
    return bytes(raw)


def lzma_zip(name: str, data: bytes) -> bytes:
    """A zip of one LZMA member whose header asks for a 4 GB dictionary: decoding allocates it first."""
    raw = bytearray(_zip([(name, data)], zipfile.ZIP_LZMA))
    name_len, extra_len = struct.unpack_from("<HH", raw, 26)
    at = 30 + name_len + extra_len + 4 + 1  # after the LZMA version, properties' size, lc/lp/pb byte
    struct.pack_into("<I", raw, at, 0xFFFFFFFF)
    return bytes(raw)


def _copies(names: list[str], data: bytes, method: int) -> bytes:
    """A zip whose members all hold ``data``, compressed once (zipfile would compress every copy)."""
    one = _zip([("x", data)], method)
    info = zipfile.ZipFile(io.BytesIO(one)).infolist()[0]
    name_len, extra_len = struct.unpack_from("<HH", one, 26)
    body = one[30 + name_len + extra_len:][:info.compress_size]
    fields = (46, 0, method, 0, 0x21, info.CRC, len(body), len(data))  # version, flags, method, time, date
    local, central = b"", b""
    for name in names:
        raw = name.encode()
        central += struct.pack("<4s6H3L5H2L", b"PK\x01\x02", 46, *fields, len(raw), 0, 0, 0, 0, 0,
                               len(local)) + raw
        local += struct.pack("<4s5H3L2H", b"PK\x03\x04", *fields, len(raw), 0) + raw + body
    end = struct.pack("<4s4H2LH", b"PK\x05\x06", 0, 0, len(names), len(names), len(central), len(local), 0)
    return local + central + end


def _slow() -> bytes:
    """48 MB of bzip2 that cost about a second of CPU to decompress (a few kB on disk)."""
    period = bytes((k * 7919 + k // 13) % 16 + 97 for k in range(5000))
    return _copies([f"alice/pad{k}.py" for k in range(48)], (period * 200)[:999_000], zipfile.ZIP_BZIP2)


def _honest() -> bytes:
    return _zip([("alice/01_x/f.py", SOURCE_TEXT.encode()), ("alice/README.md", b"notes"),
                 ("__MACOSX/alice/01_x/._f.py", b"\x00\x05\x16\x07 resource fork")])


#: planted zip -> the reason it is refused (None: the honest one)
PAYLOADS = {
    "honest": (_honest, None),
    "bomb": (lambda: _zip([(f"alice/p{k}.py", b"0" * 10_000_000) for k in range(6)]), "unpacks to more than"),
    "lying_bomb": (_lying_bomb, "is not a readable zip"),
    "members": (lambda: _zip([(f"alice/m{k}.py", b"") for k in range(1001)]), "more than 1000 members"),
    "dotdot": (lambda: _zip([("../../f.py", SOURCE_TEXT.encode())]), "'..'"),
    "absolute": (lambda: _zip([("/tmp/f.py", SOURCE_TEXT.encode())]), "absolute"),
    "backslash": (lambda: _zip([("..\\..\\f.py", SOURCE_TEXT.encode())]), "backslash"),
    "symlink": (_symlink_member, "is a symbolic link"),
    "large": (lambda: _zip([("alice/01_x/f.py", b"#" * 1_000_001)]), "larger than 1000000 bytes"),
    "corrupt": (lambda: os.urandom(5000), "is not a readable zip"),
    "truncated": (lambda: _zip([("alice/01_x/f.py", os.urandom(20_000))])[:15_000], "is not a readable zip"),
    "encrypted": (_encrypted, "is encrypted"),
    "nested": (lambda: _zip([("alice/inner.zip", _honest())]), "a zip inside the zip"),
    "twice": (lambda: _zip([("alice/f.py", b"a = 1\n"), ("alice/f.py", b"a = 2\n")]), "appears twice"),
    "deep": (lambda: _zip([("/".join(["d"] * 20) + "/f.py", b"")]), "folders deep"),
    "memory": (lambda: lzma_zip("alice/01_x/f.py", SOURCE_TEXT.encode()),
               "ran out of memory while unpacking (the sandbox's limit of 1024 MB)"),
    "slow": (_slow, "unpacking timed out"),
}

#: run as the grader would (its own folder, its cgroups): unpack every planted zip, print the outcomes
SCRIPT = r"""
import json, sys, warnings
from pathlib import Path
from mslab.grading.box import setup, teardown
from mslab.grading.owner import Owned
from mslab.grading.unpack import Limits, unpack_zip
warnings.simplefilter("ignore")
zips, mode, tmp = Path(sys.argv[1]), sys.argv[2], Path(sys.argv[3])
owned = Owned(tmp)
cgroups, _ = setup(1, owned.name)
out = {"": [owned.name, cgroups is not None]}
try:
    for path in sorted(zips.iterdir()):
        limits = Limits(mode, cgroups, 1024, 0.1 if path.stem == "slow" else 10.0, owned.folder)
        files, why = unpack_zip(path, limits)
        files = None if files is None else {k: v.decode() for k, v in files.items()}
        out[path.stem] = [files, why, sorted(p.name for p in owned.folder.iterdir())]
finally:
    teardown(cgroups)
    owned.close()
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def planted(tmp_path_factory) -> Path:
    """The planted zips, in a folder every user may read."""
    base = Path(tempfile.mkdtemp(prefix="mslab-zips-", dir="/tmp"))
    os.chmod(base, 0o755)
    zips = base / "zips"
    zips.mkdir()
    for name, (build, _) in PAYLOADS.items():
        (zips / f"{name}.zip").write_bytes(build())
        os.chmod(zips / f"{name}.zip", 0o644)
    yield zips
    shutil.rmtree(base, ignore_errors=True)


@pytest.fixture(scope="module", params=MODES)
def unpacked(request, planted) -> dict:
    """Every planted zip unpacked by a grader-like process in one isolation mode."""
    mode = request.param
    if why := _skip_reason(mode):
        pytest.skip(why)
    tmp = Path(tempfile.mkdtemp(prefix=f"mslab-zips-tmp-{mode}-", dir="/tmp"))
    os.chmod(tmp, 0o1777)
    try:
        cmd = [sys.executable, "-c", SCRIPT, str(planted), mode.removesuffix("-user"), str(tmp)]
        views = ""
        if os.geteuid() == 0 and mode.startswith("rlimits"):
            views = _open_views(tmp / "views", [sys.base_prefix, sys.prefix, str(ROOT)])
        user = "setpriv --reuid=nobody --regid=nogroup --clear-groups " if mode == "rlimits-user" else ""
        script = views + "exec " + user + " ".join(f"'{a}'" for a in cmd)
        argv = (["unshare", "--mount", "--propagation", "private"] if views else []) + ["sh", "-c", script]
        env = dict(os.environ, PYTHONPATH=str(ROOT), TMPDIR=str(tmp), HOME=str(tmp))
        proc = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        out = json.loads(proc.stdout)
        name, _ = out.pop("")
        shutil.rmtree(tmp / "views", ignore_errors=True)
        yield {"mode": mode, "out": out, "left": leftovers(tmp, [name], mark="mslab-no-mark-for-zips")}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def test_an_honest_zip_gives_its_sources_only(unpacked):
    files, why, left = unpacked["out"]["honest"]
    assert why == "" and files == {"01_x/f.py": SOURCE_TEXT}  # top folder dropped, __MACOSX and notes skipped
    assert left == [".owner"]


@pytest.mark.parametrize("name", [n for n, (_, reason) in PAYLOADS.items() if reason])
def test_a_hostile_zip_is_refused_with_its_reason(unpacked, name):
    files, why, left = unpacked["out"][name]
    assert files is None, (name, files)
    assert why.startswith(f"{name}.zip: ") and PAYLOADS[name][1] in why, why
    assert left == [".owner"], left  # nothing half-written stays in the grader's folder


def test_slow_decompression_stops_at_the_sandbox_cpu_limit(unpacked):
    """The bzip2 zip's decompression lands on the sandbox's CPU budget (0.1 s here), not the grader's."""
    files, why, _ = unpacked["out"]["slow"]
    assert "s of CPU time, the sandbox's limit" in why, why


def test_nothing_is_left(unpacked):
    assert unpacked["left"] == []


# -- the grader reads the unpacked folder as plain data ---------------------------------------------

@pytest.fixture
def tree(tmp_path) -> Path:
    (tmp_path / "out" / "01_x").mkdir(parents=True)
    (tmp_path / "out" / "01_x" / "f.py").write_text(SOURCE_TEXT)
    return tmp_path / "out"


def test_read_tree_reads_regular_source_files(tree):
    assert read_tree(tree) == ({"01_x/f.py": SOURCE_TEXT.encode()}, "")


@pytest.mark.parametrize("plant, reason", [
    (lambda t: (t / "01_x" / "g.py").symlink_to("/etc/passwd"), "not a regular file"),
    (lambda t: (t / "link").symlink_to(t.parent), "not a regular file"),
    (lambda t: os.mkfifo(t / "01_x" / "pipe.py"), "not a regular file"),
    (lambda t: os.link(t / "01_x" / "f.py", t / "01_x" / "hard.py"), "hard links"),
    (lambda t: (t / "secrets.txt").write_text("x"), "unexpected file"),
    (lambda t: (t / "big.py").write_bytes(b"#" * 1_000_001), "larger than"),
    (lambda t: (t / "many").mkdir() or [(t / "many" / f"m{k}.py").touch() for k in range(1000)], "over 1000"),
    (lambda t: (t.joinpath(*["d"] * 18)).mkdir(parents=True), "levels"),
])
def test_read_tree_refuses_what_the_unpacker_should_not_have_written(tree, plant, reason):
    plant(tree)
    files, why = read_tree(tree)
    assert files is None and reason in why, why
