"""The data that may cross the trust boundary between grader and student code.

Student code runs in a sandbox process; the only thing that comes back is *data*:
``None``, bools, numbers, strings, lists, tuples, dicts with string keys and numeric numpy
arrays. It travels as one JSON line per message (arrays as dtype, shape and base64 bytes)
and is decoded without ``pickle``: a reply can carry values, never code or objects.
The decoder is strict and bounded (:func:`loads`, :func:`decode`): ints within 64 bits,
strings of at most :data:`MAX_STRING` characters, arrays of a listed numeric dtype with at
most :data:`MAX_ELEMENTS` elements, bounded nesting and container count. No string that
crosses is ever parsed as anything but a string here; tests turn answers into numbers with
:func:`mslab.grading.checks.as_numbers`, which refuses text.

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
    if obj is None or isinstance(obj, bool):
        return obj
    if isinstance(obj, str):
        return _scalar(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return _scalar(int(obj))
    if isinstance(obj, float | np.floating):
        return float(obj)
    if isinstance(obj, complex | np.complexfloating):
        return {"__c__": [float(obj.real), float(obj.imag)]}
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind not in ARRAY_KINDS or obj.dtype.fields is not None:
            raise WireError(f"an array of dtype {obj.dtype} is not numeric data")
        if obj.ndim > MAX_NDIM or obj.size > MAX_ELEMENTS:
            raise WireError(f"an array beyond {MAX_NDIM} dimensions or {MAX_ELEMENTS} elements")
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


#: numpy dtypes allowed across the boundary (byte order, kind and size spelled out: no sub-arrays)
DTYPES = frozenset(f"{order}{code}" for order in "<>|" for code in
                   ("b1", "i1", "i2", "i4", "i8", "u1", "u2", "u4", "u8", "f2", "f4", "f8", "c8", "c16"))
#: magnitude and size limits of decoded data: ints within 64 bits, strings, array rank and size
MAX_INT, MAX_STRING, MAX_NDIM, MAX_ELEMENTS = 2**63, 4096, 8, 1 << 22


def _scalar(obj: Any) -> Any:
    if isinstance(obj, str):
        if len(obj) > MAX_STRING:
            raise WireError(f"a string longer than {MAX_STRING} characters")
    elif isinstance(obj, int) and not isinstance(obj, bool) and not -MAX_INT <= obj < MAX_INT:
        raise WireError("an integer beyond 64 bits")
    return obj


def _array(val: Any) -> np.ndarray:
    if not (isinstance(val, list) and len(val) == 3 and isinstance(val[0], str) and isinstance(val[1], list)
            and isinstance(val[2], str)):
        raise WireError("malformed array")
    dtype_str, shape, data = val
    if dtype_str not in DTYPES:
        raise WireError(f"array dtype {dtype_str[:20]!r} is not numeric")
    if len(shape) > MAX_NDIM or not all(isinstance(n, int) and 0 <= n <= MAX_ELEMENTS for n in shape):
        raise WireError(f"array shape beyond {MAX_NDIM} dimensions of at most {MAX_ELEMENTS}")
    size = 1
    for n in shape:
        size *= n
    if size > MAX_ELEMENTS:
        raise WireError(f"an array of more than {MAX_ELEMENTS} elements")
    dtype = np.dtype(dtype_str)
    if len(data) > 4 * (size * dtype.itemsize + 2) // 3 + 4:
        raise WireError("array data does not match its shape")
    raw = base64.b64decode(data, validate=True)
    if len(raw) != size * dtype.itemsize:
        raise WireError("array data does not match its shape")
    return np.frombuffer(raw, dtype=dtype).reshape(tuple(shape)).copy()


def decode(obj: Any, make_problem: Callable[[Any], Any] | None = None, depth: int = 0) -> Any:
    """Invert :func:`encode`; strict. ``make_problem(spec)`` rebuilds a test problem.

    Only plain data within the limits comes out: ints within 64 bits, strings of at most
    :data:`MAX_STRING` characters, arrays of a dtype in :data:`DTYPES` with at most
    :data:`MAX_NDIM` dimensions and :data:`MAX_ELEMENTS` elements; WireError otherwise.
    """
    if depth > MAX_DEPTH:
        raise WireError("nested too deeply")
    if obj is None or isinstance(obj, bool | int | float | str):
        return _scalar(obj)
    if isinstance(obj, list):
        return [decode(v, make_problem, depth + 1) for v in obj]
    if not isinstance(obj, dict) or len(obj) != 1:
        raise WireError("malformed message")
    (tag, val), = obj.items()
    if tag == "__nd__":
        return _array(val)
    if tag == "__c__":
        if not (isinstance(val, list) and len(val) == 2
                and all(isinstance(p, int | float) and not isinstance(p, bool) for p in val)):
            raise WireError("malformed complex number")
        return complex(float(_scalar(val[0])), float(_scalar(val[1])))
    if tag == "__t__" and isinstance(val, list):
        return tuple(decode(v, make_problem, depth + 1) for v in val)
    if tag == "__d__":
        if not isinstance(val, dict):
            raise WireError("malformed dict")
        return {_scalar(k): decode(v, make_problem, depth + 1) for k, v in val.items()}
    if tag == "__problem__" and make_problem is not None:
        return make_problem(decode(val, None, depth + 1))
    raise WireError(f"unknown tag {str(tag)[:40]!r}")


def dumps(obj: Any) -> bytes:
    """Return one message as one line of bytes (raises WireError for non-data)."""
    return json.dumps(encode(obj), separators=(",", ":")).encode() + b"\n"


#: most containers (lists, tuples, dicts) one message may hold: bounds the decoder's memory
MAX_CONTAINERS = 100_000
#: every byte but the brackets (what :func:`loads` deletes to count the nesting)
_NOT_BRACKETS = bytes(sorted(set(range(256)) - set(b"[]{}")))


def loads(line: bytes, make_problem: Callable[[Any], Any] | None = None) -> Any:
    """Decode one message line; WireError if it is not a well-formed message.

    Bounded before parsing: numbers are read with at most 21 (integers) or 64 characters
    (floats) and checked against :func:`decode`'s limits; a line with more than
    :data:`MAX_CONTAINERS` brackets or nested deeper than :data:`MAX_DEPTH` is refused
    without building it (ten million empty lists would take gigabytes).
    """
    if isinstance(line, str):
        line = line.encode()
    if line.count(b"[") + line.count(b"{") > MAX_CONTAINERS:
        raise WireError(f"more than {MAX_CONTAINERS} lists or dicts")
    depth = 0
    for byte in line.translate(None, delete=_NOT_BRACKETS):
        depth += 1 if byte in b"[{" else -1
        if depth > 3 * MAX_DEPTH + 4:
            raise WireError("nested too deeply")
    try:
        raw = json.loads(line, parse_int=_parse_int, parse_float=_parse_float)
    except (ValueError, UnicodeDecodeError, RecursionError) as err:
        raise WireError(f"not a message: {str(err)[:200]}") from None
    try:
        return decode(raw, make_problem)
    except WireError:
        raise
    except (ValueError, TypeError, KeyError, OverflowError, RecursionError) as err:
        raise WireError(f"malformed message: {type(err).__name__}") from None


def _parse_int(text: str) -> int:
    """JSON integers of at most 20 digits (int() of a long digit string is quadratic)."""
    if len(text) > 21:
        raise WireError("an integer beyond 64 bits")
    return int(text)


def _parse_float(text: str) -> float:
    if len(text) > 64:
        raise WireError("a number written with more than 64 characters")
    return float(text)
