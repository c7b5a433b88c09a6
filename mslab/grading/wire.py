"""The data that may cross the trust boundary between grader and student code.

Student code runs in a sandbox process; the only thing that comes back is *data*:
``None``, bools, numbers, strings, lists, tuples, dicts with string keys and numeric numpy
arrays. It travels as one JSON line per message (arrays as dtype, shape and base64 bytes)
and is decoded without ``pickle``: a reply can carry values, never code or objects.

This module imports numpy only (the sandbox loads it by file path, without mslab).
"""

from __future__ import annotations

import base64
import json
from collections.abc import Callable
from typing import Any

import numpy as np

#: numpy dtype kinds allowed across the boundary: bool, signed/unsigned int, float, complex
ARRAY_KINDS = "biufc"
MAX_DEPTH = 32


class WireError(ValueError):
    """A message that is not plain data (or is malformed)."""


def encode(obj: Any, depth: int = 0) -> Any:
    """Turn plain data into a JSON-able structure; anything else raises WireError."""
    if depth > MAX_DEPTH:
        raise WireError("nested too deeply")
    if obj is None or isinstance(obj, bool | str):
        return obj
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        return float(obj)
    if isinstance(obj, complex | np.complexfloating):
        return {"__c__": [float(obj.real), float(obj.imag)]}
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind not in ARRAY_KINDS or obj.dtype.fields is not None:
            raise WireError(f"an array of dtype {obj.dtype} is not numeric data")
        data = np.ascontiguousarray(obj)
        return {"__nd__": [data.dtype.str, list(data.shape), base64.b64encode(data.tobytes()).decode()]}
    if isinstance(obj, list):
        return [encode(v, depth + 1) for v in obj]
    if isinstance(obj, tuple):
        return {"__t__": [encode(v, depth + 1) for v in obj]}
    if isinstance(obj, dict):
        if not all(isinstance(k, str) for k in obj):
            raise WireError("dict keys must be strings")
        return {"__d__": {k: encode(v, depth + 1) for k, v in obj.items()}}
    spec = getattr(type(obj), "__wire__", None)
    if spec is not None and getattr(type(obj), "__module__", "").endswith("problems"):
        return {"__problem__": encode(obj.__wire__(), depth + 1)}
    raise WireError(f"an object of type {type(obj).__name__} is not plain data")


def decode(obj: Any, make_problem: Callable[[Any], Any] | None = None, depth: int = 0) -> Any:
    """Invert :func:`encode`; strict. ``make_problem(spec)`` rebuilds a test problem."""
    if depth > MAX_DEPTH:
        raise WireError("nested too deeply")
    if obj is None or isinstance(obj, bool | int | float | str):
        return obj
    if isinstance(obj, list):
        return [decode(v, make_problem, depth + 1) for v in obj]
    if not isinstance(obj, dict) or len(obj) != 1:
        raise WireError("malformed message")
    (tag, val), = obj.items()
    if tag == "__nd__":
        dtype_str, shape, data = val
        dtype = np.dtype(str(dtype_str))
        if dtype.kind not in ARRAY_KINDS or dtype.fields is not None:
            raise WireError(f"array dtype {dtype} is not numeric")
        shape = tuple(int(s) for s in shape)
        if any(s < 0 for s in shape):
            raise WireError("negative array shape")
        raw = base64.b64decode(str(data), validate=True)
        if len(raw) != int(np.prod(shape, dtype=np.int64)) * dtype.itemsize:
            raise WireError("array data does not match its shape")
        return np.frombuffer(raw, dtype=dtype).reshape(shape).copy()
    if tag == "__c__":
        return complex(float(val[0]), float(val[1]))
    if tag == "__t__":
        return tuple(decode(v, make_problem, depth + 1) for v in val)
    if tag == "__d__":
        if not isinstance(val, dict):
            raise WireError("malformed dict")
        return {str(k): decode(v, make_problem, depth + 1) for k, v in val.items()}
    if tag == "__problem__" and make_problem is not None:
        return make_problem(decode(val, None, depth + 1))
    raise WireError(f"unknown tag {tag!r}")


def dumps(obj: Any) -> bytes:
    """Return one message as one line of bytes (raises WireError for non-data)."""
    return json.dumps(encode(obj), separators=(",", ":")).encode() + b"\n"


#: most containers (lists, tuples, dicts) one message may hold: bounds the decoder's memory
MAX_CONTAINERS = 100_000


def loads(line: bytes, make_problem: Callable[[Any], Any] | None = None) -> Any:
    """Decode one message line; WireError if it is not a well-formed message.

    Bounded before parsing: a line with more than :data:`MAX_CONTAINERS` brackets or nested
    deeper than :data:`MAX_DEPTH` is refused without building it (ten million empty lists
    would take gigabytes).
    """
    if isinstance(line, str):
        line = line.encode()
    if line.count(b"[") + line.count(b"{") > MAX_CONTAINERS:
        raise WireError(f"more than {MAX_CONTAINERS} lists or dicts")
    depth = 0
    for byte in line.translate(None, delete=bytes(set(range(256)) - set(b"[]{}"))):
        depth += 1 if byte in b"[{" else -1
        if depth > 3 * MAX_DEPTH + 4:
            raise WireError("nested too deeply")
    try:
        raw = json.loads(line)
    except (ValueError, UnicodeDecodeError) as err:
        raise WireError(f"not a message: {err}") from None
    return decode(raw, make_problem)
