"""Write each exercise's ``expected.json``: the answers its public tests compare with, as numbers.

The answers come from the keys in ``tools/exercise_keys/exNN.py`` (instructor side: neither
they nor this tool are in the package or the student release). A key module holds
``CASES = {name: key}``; ``key(tests)`` gets the exercise's public test module (for the inputs
its tests define) and returns ``{"expected": [values], "mistakes": {hint: [values]}}``.

    python tools/exercise_expected.py            # (re)write every exercises/NN_topic/expected.json
    python tools/exercise_expected.py --check    # recompute and compare; exit 1 if one differs
    python tools/exercise_expected.py 03 05      # only exercises 03 and 05

``--check`` compares within a round-off bound (relative 1e-10 of each array's scale), never
bit for bit: the keys run in floating point, and a stored answer made on another CPU differs in
its last digits. Every public test that reads an answer compares with tolerances of 1e-9 or
looser.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXERCISES = ROOT / "exercises"
KEYS = Path(__file__).resolve().parent / "exercise_keys"
FILE = "expected.json"
RTOL = 1e-10


def _load(path: Path, name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _plain(values: list | tuple) -> list:
    out = []
    for a in values:
        if np.iscomplexobj(a):
            out.append({"re": np.real(a).tolist(), "im": np.imag(a).tolist()})
        elif np.ndim(a) == 0:
            out.append(float(a))
        else:
            out.append(np.asarray(a, dtype=float).tolist())
    return out


def compute(folder: Path) -> dict:
    """Return the ``expected.json`` content of one exercise folder (its key's cases, in order)."""
    key = _load(KEYS / f"ex{folder.name[:2]}.py", f"exercise_key_{folder.name[:2]}")
    tests = _load(folder / "test_public.py", f"public_tests_{folder.name[:2]}")
    data = {}
    for name, case in key.CASES.items():
        answer = case(tests)
        data[name] = {"expected": _plain(answer.get("expected", [])),
                      "mistakes": {hint: _plain(v) for hint, v in answer.get("mistakes", {}).items()}}
    return data


def _array(value: float | list | dict) -> np.ndarray:
    if isinstance(value, dict):
        return np.array(value.get("re"), dtype=float) + 1j * np.array(value.get("im"), dtype=float)
    return np.asarray(value, dtype=float)


def _values_differ(stored: list, fresh: list, where: str) -> list[str]:
    if not isinstance(stored, list) or len(stored) != len(fresh):
        return [f"{where}: the number of values differs"]
    out = []
    for i, (s, f) in enumerate(zip(stored, fresh, strict=True)):
        s_arr, f_arr = _array(s), _array(f)
        scale = float(np.max(np.abs(f_arr), initial=0.0))
        if s_arr.shape != f_arr.shape or not np.allclose(s_arr, f_arr, rtol=RTOL, atol=RTOL * scale):
            out.append(f"{where}[{i}]: stored and fresh differ beyond round-off")
    return out


def differences(stored: dict, fresh: dict) -> list[str]:
    """What differs between two answer files beyond round-off: cases, hints, shapes or values."""
    if set(stored) != set(fresh):
        return [f"cases {sorted(stored)} != {sorted(fresh)}"]
    out = []
    for name, f in fresh.items():
        s = stored[name]
        out += _values_differ(s.get("expected"), f["expected"], f"{name}: expected")
        if set(s.get("mistakes", {})) != set(f["mistakes"]):
            out.append(f"{name}: the mistakes' hints differ")
            continue
        for hint, values in f["mistakes"].items():
            out += _values_differ(s["mistakes"][hint], values, f"{name}: {hint[:40]}")
    return out


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` compare) every exercise's ``expected.json``."""
    parser = argparse.ArgumentParser(description="write the public tests' expected answers; --check compares")
    parser.add_argument("--check", action="store_true", help="recompute and compare with the stored files")
    parser.add_argument("only", nargs="*", help="exercise numbers (e.g. 03 05); default: all")
    args = parser.parse_args(argv)
    status = 0
    sys.path[:0] = [str(ROOT), str(KEYS)]  # a key may use another's (exercise 12 steps like 04)
    keyed = (p for p in EXERCISES.iterdir() if p.is_dir() and (KEYS / f"ex{p.name[:2]}.py").exists())
    for folder in sorted(p for p in keyed if not args.only or p.name[:2] in args.only):
        fresh, out = compute(folder), folder / FILE
        rel = out.relative_to(ROOT)
        if args.check:
            stored = json.loads(out.read_text()) if out.exists() else {}
            diff = differences(stored, fresh)
            print(f"{rel}: {'reproduced' if not diff else 'DIFFERS: ' + '; '.join(diff[:3])}")
            status |= bool(diff)
        else:
            cases = (f" {json.dumps(name)}: {json.dumps(case)}" for name, case in fresh.items())
            out.write_text("{\n" + ",\n".join(cases) + "\n}\n")
            print(f"wrote {rel}")
    return status


if __name__ == "__main__":
    sys.exit(main())
