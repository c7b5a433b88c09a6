"""Declarative schemas of effect parameters: one :class:`Key` per TOML key / builder argument.

An effect lists its keys once; the same records check a TOML section (``load_scene``), the
arguments of its ``SceneBuilder`` method, and write the scene-format table of
``docs/scenes.md``. :func:`check_values` turns raw values (TOML data or Python/numpy values)
into checked plain values, raising one :class:`~mslab.errors.SceneError` naming the key.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mslab.errors import SceneError


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


#: default of a key that must be given
REQUIRED: Any = _Required()

#: the value types a :class:`Key` can hold, with their wording in the docs
TYPES = {
    "number": "number",
    "integer": "whole number",
    "string": "string",
    "bool": "true or false",
    "vector": "vector",
    "number|vector": "number or vector",
    "numbers": "number or list",
    "pairs": "list of [i, j]",
    "indices": "list of indices",
    "vectors": "list of vectors",
}


@dataclass(frozen=True)
class Key:
    """One parameter of an effect: a TOML key and the builder argument of the same name.

    Parameters
    ----------
    name : str
        Key in the TOML section and keyword of the builder method.
    type : str
        One of :data:`TYPES`: ``"number"``, ``"integer"``, ``"string"``, ``"bool"``,
        ``"vector"`` (``dim`` numbers), ``"number|vector"``, ``"numbers"`` (one number, or
        one per entry of the key named by ``per``), ``"pairs"`` (``[i, j]`` particle
        index pairs), ``"indices"`` (particle indices), ``"vectors"`` (one ``dim``-vector
        per entry of ``per``).
    default : object
        Value when the key is absent; :data:`REQUIRED` when it must be given; ``None``
        for "absent" (the effect decides, e.g. a rest length from the initial positions).
    low : float, optional
        Lower bound of numbers; ``strict`` makes it exclusive (``> low``).
    unit : str
        SI unit, for the docs (``"N/m"``).
    doc : str
        One line: what the key means.
    choices : tuple of str
        Allowed strings.
    per : str, optional
        Name of the list key whose length a ``numbers`` or ``vectors`` value must match.
    default_doc : str, optional
        How the docs describe the default (when the value alone does not say it).
    """

    name: str
    type: str = "number"
    default: Any = REQUIRED
    low: float | None = None
    strict: bool = False
    unit: str = ""
    doc: str = ""
    choices: tuple[str, ...] = ()
    per: str | None = None
    default_doc: str | None = None

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ValueError(f"Key {self.name!r}: unknown type {self.type!r}; valid: {', '.join(TYPES)}")

    @property
    def required(self) -> bool:
        """Whether the key must be given (no default)."""
        return self.default is REQUIRED

    def type_text(self) -> str:
        """Return the value type in words (docs)."""
        text = TYPES[self.type]
        if self.per is not None and self.type in ("numbers", "vectors"):
            text += f" (one per entry of `{self.per}`)"
        return text

    def range_text(self) -> str:
        """Return the allowed range in words (docs): ``> 0``, ``>= 0``, the choices."""
        if self.choices:
            return ", ".join(f'`"{c}"`' for c in self.choices)
        if self.low is not None:
            return f"{'>' if self.strict else '>='} {self.low:g}"
        return ""

    def default_text(self) -> str:
        """Return the default in words (docs)."""
        if self.default_doc is not None:
            return self.default_doc
        if self.required:
            return "required"
        if self.default is None:
            return "–"
        if isinstance(self.default, str):
            return f'`"{self.default}"`'
        if isinstance(self.default, bool):
            return f"`{str(self.default).lower()}`"
        return f"`{self.default!r}`"


def suggest(word: str, valid: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the nearest valid name, or ``""``."""
    close = difflib.get_close_matches(str(word), list(valid), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def describe(value: Any) -> str:
    """Describe a raw value in words, for error messages: ``the string '100'``, ``a list of 3``."""
    if isinstance(value, bool | np.bool_):
        return f"the boolean {str(bool(value)).lower()}"
    if isinstance(value, str):
        return f"the string '{value}'"
    if isinstance(value, int | float | np.integer | np.floating):
        return f"the number {value}"
    if isinstance(value, list | tuple):
        return f"a list of {len(value)}"
    if isinstance(value, dict):
        return "a table"
    return type(value).__name__


def _plain(value: Any):
    """Turn numpy arrays and scalars into lists and Python numbers (TOML-like data)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _is_number(value: Any) -> bool:
    numeric = isinstance(value, int | float | np.integer | np.floating)
    return numeric and not isinstance(value, bool | np.bool_)


def number(value: Any, name: str, low: float | None = None, strict: bool = False) -> float:
    """Return a finite number (bounded below by ``low``), or raise SceneError naming ``name``."""
    if not _is_number(value):
        raise SceneError(name, f"must be a number, got {describe(value)}")
    value = float(value)
    if not np.isfinite(value):
        raise SceneError(name, f"must be a finite number, got {value}")
    if low is not None and (value <= low if strict else value < low):
        raise SceneError(name, f"must be {'>' if strict else '>='} {low:g}, got {value:g}")
    return value


def integer(value: Any, name: str, low: int | None = None) -> int:
    """Return a whole number (>= ``low``), or raise SceneError naming ``name``."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise SceneError(name, f"must be a whole number, got {describe(value)}")
    if low is not None and value < low:
        raise SceneError(name, f"must be >= {low}, got {value}")
    return int(value)


def string(value: Any, name: str, choices: Iterable[str] | None = None) -> str:
    """Return a string (one of ``choices``), or raise SceneError naming ``name`` with the nearest choice."""
    if not isinstance(value, str):
        raise SceneError(name, f"must be a string, got {describe(value)}")
    if choices is not None:
        choices = tuple(choices)
        if value not in choices:
            raise SceneError(name, f"unknown value '{value}'{suggest(value, choices)}; "
                             f"valid: {', '.join(choices)}")
    return value


def vector(value: Any, name: str, dim: int) -> np.ndarray:
    """Return ``value`` checked as a list of ``dim`` finite numbers."""
    value = _plain(value)
    if not isinstance(value, list) or len(value) != dim:
        raise SceneError(name, f"must be a list of {dim} numbers, got {describe(value)}")
    return np.array([number(c, f"{name}[{i}]") for i, c in enumerate(value)])


def vectors(value: Any, name: str, dim: int, n: int | None = None) -> np.ndarray:
    """Return ``value`` checked as a non-empty list of ``dim``-vectors (``n`` when given), shape (m, dim)."""
    value = _plain(value)
    if not isinstance(value, list) or not value:
        raise SceneError(name, f"must be a non-empty list of {dim}-vectors, got {describe(value)}")
    if n is not None and len(value) != n:
        raise SceneError(name, f"must have one entry per particle ({n}), got {len(value)}")
    return np.array([vector(p, f"{name}[{i}]", dim) for i, p in enumerate(value)]).reshape(-1, dim)


def numbers(value: Any, name: str, n: int, low: float | None = None, strict: bool = False) -> np.ndarray:
    """Return ``value`` checked as one number for all, or a list of ``n`` numbers; shape (n,)."""
    value = _plain(value)
    if isinstance(value, list):
        if len(value) != n:
            raise SceneError(name, f"must be one number or a list of {n} numbers, got a list of {len(value)}")
        return np.array([number(c, f"{name}[{i}]", low, strict) for i, c in enumerate(value)], dtype=float)
    return np.full(n, number(value, name, low, strict))


def index(value: Any, name: str, n: int) -> int:
    """Return ``value`` checked as a particle index in ``0..n-1``."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise SceneError(name, f"particle index must be a whole number, got {describe(value)}")
    if not 0 <= value < n:
        raise SceneError(name, f"particle index {value} out of range 0..{n - 1}")
    return int(value)


def indices(value: Any, name: str, n: int) -> np.ndarray:
    """Return ``value`` checked as a non-empty list of particle indices, int64 array."""
    value = _plain(value)
    if not isinstance(value, list) or not value:
        raise SceneError(name, f"must be a non-empty list of particle indices, got {describe(value)}")
    return np.array([index(k, f"{name}[{q}]", n) for q, k in enumerate(value)], dtype=np.int64)


def pairs(value: Any, name: str, n: int) -> np.ndarray:
    """Return ``value`` checked as a non-empty list of ``[i, j]`` pairs, ``i != j``; int64 array (m, 2)."""
    if isinstance(value, np.ndarray) and value.ndim == 2 and value.shape[1] == 2 \
            and np.issubdtype(value.dtype, np.integer) and value.shape[0] > 0:
        out = value.astype(np.int64)  # fast path for large generated arrays
        bad = np.flatnonzero((out < 0).any(axis=1) | (out >= n).any(axis=1) | (out[:, 0] == out[:, 1]))
        if bad.size == 0:
            return out
        value = out[: bad[0] + 1].tolist()
    value = _plain(value)
    if not isinstance(value, list) or not value:
        raise SceneError(name, f"must be a non-empty list of [i, j] index pairs, got {describe(value)}")
    out = np.empty((len(value), 2), dtype=np.int64)
    for s, pair in enumerate(value):
        if not isinstance(pair, list) or len(pair) != 2:
            raise SceneError(f"{name}[{s}]", f"must be a pair [i, j], got {describe(pair)}")
        i, j = (index(k, f"{name}[{s}]", n) for k in pair)
        if i == j:
            raise SceneError(f"{name}[{s}]", f"a spring needs two different particles, got [{i}, {j}]")
        out[s] = i, j
    return out


def check_keys(table: Mapping, valid: Iterable[str], prefix: str = "", what: str = "key") -> None:
    """SceneError for the first key of ``table`` not in ``valid`` (nearest name suggested)."""
    valid = tuple(valid)
    for k in table:
        if k not in valid:
            raise SceneError(f"{prefix}{k}", f"unknown {what}{suggest(k, valid)}; "
                             f"valid {what}s: {', '.join(valid)}")


def check_value(key: Key, value: Any, name: str, dim: int, n: int, sizes: Mapping[str, int]) -> Any:
    """Return one checked value of ``key`` (``name`` is its full dotted name in messages)."""
    t = key.type
    if t == "number":
        return number(value, name, key.low, key.strict)
    if t == "integer":
        return integer(value, name, None if key.low is None else int(key.low))
    if t == "string":
        return string(value, name, key.choices or None)
    if t == "bool":
        if not isinstance(value, bool | np.bool_):
            raise SceneError(name, f"must be true or false, got {describe(value)}")
        return bool(value)
    if t == "vector":
        return vector(value, name, dim)
    if t == "number|vector":
        if isinstance(_plain(value), list):
            return vector(value, name, dim)
        return number(value, name, key.low, key.strict)
    if t == "pairs":
        return pairs(value, name, n)
    if t == "indices":
        return indices(value, name, n)
    count = sizes.get(key.per) if key.per is not None else None
    if t == "numbers":
        if count is None:
            return number(value, name, key.low, key.strict)
        return numbers(value, name, count, key.low, key.strict)
    return vectors(value, name, dim, count)  # "vectors"


def check_values(keys: Iterable[Key], raw: Mapping, prefix: str, dim: int, n: int,
                 missing_hint: str = "") -> dict:
    """Check a table of raw values against ``keys``; return every key's checked value.

    Unknown keys, missing required keys, wrong types, non-finite numbers, out-of-range
    values and indices each raise one :class:`SceneError` named ``prefix + key``.
    Absent optional keys take their default. ``n`` is the number of particles that
    indices refer to.
    """
    keys = tuple(keys)
    check_keys(raw, [k.name for k in keys], prefix)
    out: dict = {}
    sizes: dict[str, int] = {}
    for key in keys:
        name = f"{prefix}{key.name}"
        if key.name not in raw or raw[key.name] is None:
            if key.required:
                doc = f": {key.doc}" if key.doc else missing_hint
                unit = f" in {key.unit}" if key.unit and key.doc else ""
                raise SceneError(name, f"missing{doc}{unit}")
            out[key.name] = key.default
            continue
        out[key.name] = value = check_value(key, raw[key.name], name, dim, n, sizes)
        if isinstance(value, np.ndarray) and value.ndim >= 1:
            sizes[key.name] = value.shape[0]
    return out
