"""The Effect protocol and helpers shared by all force terms.

An *effect* is one force term of Newton's second law (lecture notes, eq. 3), defined in one module of
``mslab/effects/`` that owns

* ``force(x, v)`` — the force on every particle, shape ``(n_particles, dim)``;
* ``energy(x)`` — its potential energy when it is conservative (else 0);
* ``power(x, v)`` — the power it dissipates (>= 0) when it is dissipative (else 0);
* ``external_work(x, x0)`` — for a *driving* effect (wind), the work its external drive has
  put into the system while the particles moved from ``x0`` to ``x`` (``external_power(x, v)``
  its rate), so that the energy ledger ``K + U + D - W_ext`` is constant (see
  :class:`~mslab.trajectory.Energy`); 0 for every other effect;
* ``jacobians(x, v)`` — ``(df/dx, df/dv)`` as ``scipy.sparse`` matrices of shape
  ``(n*dim, n*dim)`` (``None`` for a block that is identically zero), used by the
  implicit methods and by the stability analysis;
* its scene-file section and the schema of its keys (:class:`~mslab.effects.schema.Key`),
  its ``SceneBuilder`` method(s), how it is built (:meth:`Effect.create`);
* optionally a compiled kernel: a plain module-level function in numba-compatible style,
  ``kernel(x, v, f, *params) -> float``, that adds the force into ``f`` and returns the
  dissipated power, with :meth:`Effect.kernel_params` giving ``params``.

The flags ``velocity_dependent``, ``dissipative`` and ``driving`` let the :class:`~mslab.system.System`
skip work that no effect of the scene asks for. ``docs/extending.md`` shows a complete
example; :mod:`mslab.effects.registry` finds the modules.

*Capabilities*: code outside ``mslab/effects/`` never picks an effect by name or class; it
asks what an effect declares (None or False: "not this kind of force")

* :meth:`Effect.hooke_springs` — Hooke springs ``(i, j, k, L)`` (the fast mass-spring
  method's local step, the scene's spring table);
* :meth:`Effect.linear_drag` — the ``gamma`` of ``f = -gamma v`` (the global matrix of the
  fast mass-spring method, implicit Euler's objective for Newton's line search);
* :meth:`Effect.constant_force` — the force when it is one fixed array (gravity);
* :attr:`Effect.may_touch` and :meth:`Effect.contact_jacobian` — a contact force that
  switches on where particles touch (the stability analysis of possible contacts);
* :meth:`Effect.outline` — the solid an effect stands for, :class:`Halfspace` or
  :class:`Ball` (the plots draw it).

Effects import nothing above them: the builder they record into is the protocol
:class:`Builder` (implemented by :class:`mslab.scenes.builder.SceneBuilder`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple, Protocol

import numpy as np

from mslab.effects.schema import Key

if TYPE_CHECKING:  # scipy.sparse is imported on first use: `import mslab` stays cheap
    import scipy.sparse as sp

    from mslab.errors import SceneError


class Builder(Protocol):
    """What an effect's builder methods and ``from_toml`` use of a scene builder.

    :class:`mslab.scenes.builder.SceneBuilder` implements it; effects import this protocol,
    never the scenes package above them.
    """

    dim: int

    @property
    def n_particles(self) -> int: ...  # noqa: D102

    def positions(self) -> np.ndarray: ...  # noqa: D102

    def entries(self, effect: type[Effect]) -> list: ...  # noqa: D102

    def add_effect(self, effect: type[Effect], **raw: Any) -> None: ...  # noqa: D102

    def check_effect(self, effect: type[Effect], raw: dict, prefix: str,  # noqa: D102
                     n: int | None = None) -> dict: ...

    def check_table(self, value: Any, key: str) -> dict: ...  # noqa: D102

    def error(self, key: str, reason: str) -> SceneError: ...  # noqa: D102


class Body(Protocol):
    """What a ``per_body`` section's ``from_toml`` knows of its body (:class:`mslab.scenes.bodies.Body`)."""

    first: int
    n: int
    generator: str | None

    def generated_pairs(self, kind: str) -> np.ndarray: ...  # noqa: D102


class HookeSprings(NamedTuple):
    """Hooke springs between particle pairs, as an effect declares them (:meth:`Effect.hooke_springs`).

    For the pair ``(i[q], j[q])``, ``f_i = k (L - l) u = -f_j`` (lecture notes, eq. 2); shapes (n_springs,).
    ``kind``: a label per spring (``structural``, ``shear``, ``bend`` ...).
    """

    i: np.ndarray
    j: np.ndarray
    stiffness: np.ndarray
    rest_length: np.ndarray
    kind: np.ndarray


class Halfspace(NamedTuple):
    """The solid ``normal . x <= offset`` behind the plane ``normal . x = offset`` (unit ``normal``)."""

    normal: np.ndarray
    offset: float


class Ball(NamedTuple):
    """The ball (a disc in 2D) of centre ``center``, shape (dim,), and radius ``radius``."""

    center: np.ndarray
    radius: float


@dataclass(frozen=True)
class BuildContext:
    """What ``SceneBuilder.build`` knows when it creates the effects.

    Attributes
    ----------
    x, v : ndarray, shape (n_particles, dim)
        Initial positions and velocities.
    mass : ndarray, shape (n_particles,)
    pinned : ndarray of bool, shape (n_particles,)
    dim : int
    """

    x: np.ndarray
    v: np.ndarray
    mass: np.ndarray
    pinned: np.ndarray
    dim: int

    @property
    def n_particles(self) -> int:
        """Number of particles."""
        return self.x.shape[0]


class Effect:
    """Base class of a force term. Subclasses set the class attributes and the methods.

    Class attributes read by the registry, the builder, the loader and the docs
    ---------------------------------------------------------------------------
    name : str
        The effect's name in ``scene.effects`` and in messages.
    section : str or None
        Its TOML section (``"gravity"`` for ``[gravity]``); None: not in scene files.
    many : bool
        The section is an array of tables (``[[colliders]]``) whose ``type`` key is
        :attr:`kind`; each table adds one effect.
    kind : str or None
        The ``type`` value that selects this effect in a ``many`` section.
    per_body : bool
        The section belongs to a body (``[springs.<kind>]`` beside ``[particles]``, or
        ``[bodies.springs.<kind>]``); indices count within the body.
    kinds : tuple of str
        Sub-table names of a ``per_body`` section (``structural``, ``shear``, ``bend``).
    keys : tuple of Key
        The schema: TOML keys, also the keyword arguments of the builder method.
    builder_methods : tuple of str
        Names of the ``SceneBuilder`` methods this effect provides: functions of the
        same names on the class taking ``(builder, ...)`` (see :meth:`add`).
    unique : bool
        A scene holds at most one: adding it again replaces the first.
    order : int
        Position among the System's effects (summation order of forces).
    internal : bool
        Forces between particles only: they sum to zero (momentum is conserved).
    summary : str
        One line for the scene-format table.
    kernel : callable or None
        The compiled kernel (a plain function, set with ``kernel = staticmethod(f)``).
    kick_kernel : callable or None
        A twin of ``kernel`` that also does the splitting loop's kick pass, returning ``(power,
        bad)`` (:mod:`mslab.effects.spring_kick`); used where the kernel is the scene's last.
    may_touch : bool
        A contact force: zero until a particle touches, then a penalty (capability, see
        :meth:`contact_jacobian`).
    """

    name: ClassVar[str] = "effect"
    section: ClassVar[str | None] = None
    many: ClassVar[bool] = False
    kind: ClassVar[str | None] = None
    per_body: ClassVar[bool] = False
    kinds: ClassVar[tuple[str, ...]] = ()
    keys: ClassVar[tuple[Key, ...]] = ()
    builder_methods: ClassVar[tuple[str, ...]] = ()
    unique: ClassVar[bool] = False
    order: ClassVar[int] = 50
    internal: ClassVar[bool] = False
    summary: ClassVar[str] = ""
    kernel: ClassVar[Callable[..., float] | None] = None
    kick_kernel: ClassVar[Callable[..., tuple[float, int]] | None] = None
    may_touch: ClassVar[bool] = False

    velocity_dependent: bool = False
    dissipative: bool = False
    conservative: bool = True
    driving: bool = False

    # -- physics ---------------------------------------------------------------------------------
    def force(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Force on every particle, shape (n_particles, dim)."""
        raise NotImplementedError

    def force_and_power(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        """Force and dissipated power from one pass (default: two calls)."""
        f = self.force(x, v)
        return f, (self.power(x, v) if self.dissipative else 0.0)

    def energy(self, x: np.ndarray) -> float:
        """Potential energy (0 unless conservative)."""
        return 0.0

    def energies(self, xs: np.ndarray) -> np.ndarray:
        """:meth:`energy` of each state of ``xs`` (k, n, dim), bitwise (default: one by one)."""
        return np.array([self.energy(x) for x in xs], dtype=float)

    def compiled_energy(self, x: np.ndarray) -> float:
        """:meth:`energy` for the ledger check of a compiled run (default: the numpy code).

        An effect whose energy costs enough to matter (springs) overrides it with a compiled
        loop of the same equation (equal to round-off, tested).
        """
        return self.energy(x)

    def power(self, x: np.ndarray, v: np.ndarray) -> float:
        """Dissipated power, >= 0 (0 unless dissipative)."""
        return 0.0

    def external_power(self, x: np.ndarray, v: np.ndarray) -> float:
        """Power put into the system by an external drive (0 unless ``driving``).

        With it, ``power(x, v) - external_power(x, v)`` is the power the non-conservative
        part of the force removes, ``-(f(x, v) - f(x, 0)) . v``.
        """
        return 0.0

    def external_work(self, x: np.ndarray, x0: np.ndarray) -> float:
        """Work the external drive did on particles moved from ``x0`` to ``x`` (0 unless ``driving``).

        The drive must be a constant force, so that its work depends only on the end
        points: ``d/dt external_work(x(t), x0) = external_power(x, v)``. The energy ledger
        evaluates it at every saved state, whichever loop (numpy or compiled) stepped.
        """
        return 0.0

    def jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple[sp.spmatrix | None, sp.spmatrix | None]:
        """``(df/dx, df/dv)``, sparse (n*dim, n*dim); None for a block that is zero."""
        raise NotImplementedError

    def compiled_jacobians(self, x: np.ndarray, v: np.ndarray) -> tuple:
        """:meth:`jacobians` for the compiled Newton path (:mod:`mslab.fast.newton`).

        Default: the numpy code. An effect whose Jacobians cost enough to matter (springs)
        overrides it with a compiled loop of the same equations (tested equal).
        """
        return self.jacobians(x, v)

    # -- capabilities: what code outside effects/ may ask (module docstring) -----------------------
    def hooke_springs(self) -> HookeSprings | None:
        """Return ``(i, j, k, L)`` when the force at ``v = 0`` is exactly Hooke springs between pairs.

        Any velocity-dependent remainder ``f(x, v) - f(x, 0)`` (damping along the springs)
        is the effect's own. None (default): not Hooke springs.
        """
        return None

    def linear_drag(self) -> float | None:
        """Return ``gamma`` when the force is exactly ``f = -gamma v`` on every particle; else None."""
        return None

    def constant_force(self) -> np.ndarray | None:
        """Return the force (n_particles, dim) when it depends on neither x nor v (gravity); else None."""
        return None

    def contact_jacobian(self, x: np.ndarray) -> sp.csr_matrix:
        """``df/dx`` of a contact force (:attr:`may_touch`) as if every particle touched, at ``x``.

        The stiffest linearisation the contact can have near ``x``: the stability analysis
        of possible contacts uses it. Only for ``may_touch`` effects.
        """
        raise NotImplementedError(f"effect '{self.name}' is not a contact force")

    def outline(self) -> Halfspace | Ball | None:
        """Return the solid the effect stands for (a collider's), to be drawn; None (default): none."""
        return None

    def kernel_params(self) -> tuple:
        """Trailing arguments of :attr:`kernel`: contiguous float64/int64 arrays and scalars."""
        raise NotImplementedError(f"effect '{self.name}' has no compiled kernel")

    def kernel_items(self, n_particles: int) -> int:
        """Return how many items :attr:`kernel` loops over (the cost model of ``backend="auto"``).

        Default: the length of the longest array in :meth:`kernel_params` (springs, anchors),
        else ``n_particles``; an effect whose kernel visits every particle whatever its
        parameters (a collider) returns ``n_particles``.
        """
        sizes = [len(p) for p in self.kernel_params() if isinstance(p, np.ndarray) and p.ndim >= 1]
        return max(sizes, default=n_particles)

    # -- scene description -----------------------------------------------------------------------
    @classmethod
    def add(cls, builder: Builder, values: dict, prefix: str = "") -> None:
        """Record checked ``values`` in the builder (default: one entry per call).

        ``builder.entries(cls)`` is the list :meth:`build` receives; a ``unique`` effect
        keeps only the last entry. Checks beyond the schema raise ``SceneError`` with
        keys starting with ``prefix`` (the TOML location, or ``section.`` for the builder).
        """
        entries = builder.entries(cls)
        if cls.unique:
            entries.clear()
        entries.append(values)

    @classmethod
    def from_toml(cls, builder: Builder, raw: dict, prefix: str, body: Body | None = None) -> None:
        """Add this effect from its raw TOML table (default: check it against :attr:`keys`, then :meth:`add`).

        ``prefix`` starts every error key (``colliders[0].``); ``body`` describes the body
        of a ``per_body`` section (first particle, count, generator).
        """
        table = {k: v for k, v in raw.items() if k != "type" or not cls.many}
        values = builder.check_effect(cls, table, prefix)
        cls.add(builder, values, prefix)

    @classmethod
    def build(cls, entries: list, ctx: BuildContext) -> list[Effect]:
        """Return the effects of a scene from the builder's entries (default: :meth:`create` each)."""
        made = (cls.create(values, ctx) for values in entries)
        return [e for e in made if e is not None]

    @classmethod
    def create(cls, values: dict, ctx: BuildContext) -> Effect | None:
        """One effect from one entry's values (None: nothing to build, e.g. zero drag)."""
        raise NotImplementedError

    @classmethod
    def example(cls, dim: int) -> dict:
        """Values of one section for the registry-wide tests: 6 particles in [-1, 1]^dim."""
        raise NotImplementedError

    @classmethod
    def toml_fragment(cls, values: dict) -> dict:
        """Return a scene-file fragment holding one section of ``values`` (for round-trip tests and docs)."""
        if cls.many:
            return {cls.section: [{"type": cls.kind, **values}]}
        return {cls.section: dict(values)}

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def block_diagonal(blocks: np.ndarray, particles: np.ndarray, n: int) -> sp.csr_matrix:
    """Sparse ``(n*dim, n*dim)`` matrix with ``blocks[k]`` at particle ``particles[k]``.

    ``blocks`` has shape ``(m, dim, dim)``; repeated particles are summed.
    """
    import scipy.sparse as sp

    m, dim, _ = blocks.shape
    rows = (particles[:, None] * dim + np.arange(dim)[None, :])  # (m, dim)
    r = np.repeat(rows, dim, axis=1).ravel()
    c = np.tile(rows, (1, dim)).ravel()
    return sp.csr_matrix((blocks.ravel(), (r, c)), shape=(n * dim, n * dim))


def pair_blocks(blocks: np.ndarray, i: np.ndarray, j: np.ndarray, n: int) -> sp.csr_matrix:
    """Sparse matrix of pair interactions: ``+B`` at (i,i), (j,j) and ``-B`` at (i,j), (j,i).

    This is the pattern of any force that depends on ``x_i - x_j`` only (a spring):
    with ``B = df_i/dx_i`` we have ``df_i/dx_j = -B``, ``df_j/dx_j = B``, ``df_j/dx_i = -B``.
    """
    import scipy.sparse as sp

    m, dim, _ = blocks.shape
    ri = i[:, None] * dim + np.arange(dim)[None, :]
    rj = j[:, None] * dim + np.arange(dim)[None, :]

    def grid(a: np.ndarray, b: np.ndarray):
        return np.repeat(a, dim, axis=1).ravel(), np.tile(b, (1, dim)).ravel()

    parts = [(grid(ri, ri), blocks), (grid(rj, rj), blocks),
             (grid(ri, rj), -blocks), (grid(rj, ri), -blocks)]
    r = np.concatenate([p[0][0] for p in parts])
    c = np.concatenate([p[0][1] for p in parts])
    d = np.concatenate([p[1].ravel() for p in parts])
    return sp.csr_matrix((d, (r, c)), shape=(n * dim, n * dim))
