"""Splitting methods: alternating drifts ``x += a_i h v`` and kicks ``v += b_i h a``.

A splitting method with drift coefficients ``a_0 .. a_k`` and kick coefficients
``b_0 .. b_(k-1)`` steps, drift first::

    x += a_0 h v;  v += b_0 h a(x, v);  x += a_1 h v;  ...;  v += b_(k-1) h a(x, v);  x += a_k h v

Each drift is the exact flow of ``x' = v`` and each kick that of ``v' = a(x)`` for
position-dependent forces, so every such method is symplectic. The coefficients are all
there is to a method: symplectic Euler is ``drift = [0, 1], kick = [1]`` (velocity first),
its adjoint ``drift = [1, 0], kick = [1]``, velocity Verlet ``drift = [0, 1, 0],
kick = [1/2, 1/2]``, Forest-Ruth a three-kick composition of order 4.

**First same as last.** When ``a_0 = a_k = 0`` the last kick of a step and the first
kick of the next one evaluate the force at the same positions: the acceleration is kept
in ``State.memory`` and reused, so such a method costs ``k - 1`` force evaluations per
step (plus one in ``start``) — as long as no force depends on velocity.

**Velocity-dependent forces (damping, friction) — this family's choice.** Then a kick is
no exact flow any more: it is the flow of ``v' = a(x, v)`` with x held fixed, and a
splitting of order p keeps its order when each kick approximates that flow to
``O(h^(p+1))``. So a kick takes one step of the explicit Runge-Kutta method of the
splitting's order on that sub-problem (:data:`KICK_METHODS`: ``euler`` for order 1 —
which is exactly the course's symplectic Euler, eqs. 7-10 of the lecture notes — ``midpoint``, ``rk3``,
``rk4``, and ``rk6`` for orders 5 and 6), with ``s`` counted force evaluations per kick.
Forces that depend on positions only make every stage equal, so then a kick costs one
evaluation. The dissipated power is booked with the sub-step's weights ``b_i h b_j``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np

from mslab.integrators.base import Integrator, get_method
from mslab.integrators.families.coefficients import as_given, frozen
from mslab.state import State

if TYPE_CHECKING:
    from mslab.integrators.families.runge_kutta import ExplicitRK
    from mslab.system import System

#: The explicit Runge-Kutta method that integrates a kick with velocity-dependent forces,
#: by the splitting's order.
KICK_METHODS = {1: "euler", 2: "midpoint", 3: "rk3", 4: "rk4", 5: "rk6", 6: "rk6"}


class Splitting(Integrator):
    """A drift/kick splitting method (see the module docstring for the update equations).

    Parameters
    ----------
    drift : array_like, shape (k + 1,)
        ``a_0 .. a_k``, the drift weights (first and last may be 0).
    kick : array_like, shape (k,)
        ``b_0 .. b_(k-1)``, the kick weights.
    name : str
    order : int
        Declared order (checked by the registry-wide tests and :func:`mslab.derive.order`).
    doc : str, optional
        The method's docstring.

    Cost: ``k`` force evaluations per step, ``k - 1`` when the first and last drift are
    zero and forces depend on positions only. Stability on the oscillator: the product of
    the drift and kick shear matrices (:meth:`oscillator_matrix`).
    """

    family = "splitting"
    explicit = True
    symplectic = True
    def __init__(self, drift: Iterable[Any], kick: Iterable[Any], name: str = "splitting",
                 order: int = 0, doc: str | None = None):
        self.coefficients = {"drift": as_given(drift), "kick": as_given(kick)}
        self.drift = frozen(drift, 1)
        self.kick = frozen(kick, 1)
        if self.drift.size != self.kick.size + 1 or self.kick.size == 0:
            raise ValueError(f"a splitting needs len(drift) == len(kick) + 1 >= 2, got {self.drift.size} "
                             f"drift and {self.kick.size} kick coefficients")
        self.name = name
        self.order = int(order)
        self.fsal = bool(self.drift[0] == 0.0 and self.drift[-1] == 0.0 and self.kick.size > 1)
        self.n_stages = self.kick.size - (1 if self.fsal else 0)
        self.n_start = 1 if self.fsal else 0
        if self.order > max(KICK_METHODS):
            raise ValueError(f"splitting {name!r}: no kick integrator for order {self.order} "
                             f"(velocity-dependent forces need one of order >= {self.order})")
        if doc:
            self.__doc__ = doc

    @property
    def kick_method(self) -> ExplicitRK:
        """The explicit Runge-Kutta method of this order that steps kicks with velocity-dependent forces."""
        return get_method(KICK_METHODS[max(self.order, 1)])

    @property
    def compiled(self) -> tuple[str, tuple]:
        """The generic compiled splitting loop over ``drift, kick``."""
        return "splitting", (self.drift, self.kick)

    def evaluations_per_step(self, system: System) -> int:
        """Force evaluations per step: :attr:`n_stages`, or every kick's Runge-Kutta stages (cost: O(1))."""
        if not system.velocity_dependent:
            return max(1, self.n_stages)
        return self.kick.size * self.kick_method.n_stages

    def _reuses(self, system: System) -> bool:
        return self.fsal and not system.velocity_dependent

    def start(self, system: System, state: State, dt: float) -> State:
        """Evaluate the first acceleration once when it is reused from step to step."""
        if not self._reuses(system):
            return state
        a, p = system.rhs(state.x, state.v)
        return State(state.x, state.v, (a, p), state.dissipated)

    def _kick(self, system: System, x: np.ndarray, v: np.ndarray, bh: float):
        """``v' = v + bh a(x, v)``, by :attr:`kick_method` when forces depend on velocity."""
        a, p = system.rhs(x, v)
        if not system.velocity_dependent:
            return v + bh * a, p
        rk = self.kick_method
        _, accs, powers = rk.stages(system, x, v, bh, first=(a, p), hold_x=True)
        new, power = v, 0.0
        for bi, a, p in zip(rk.b, accs, powers, strict=True):
            if bi != 0.0:
                new = new + (bh * bi) * a
                power += bi * p
        return new, power

    def step(self, system: System, state: State, dt: float) -> State:
        """One step: drifts and kicks in turn (see the class docstring)."""
        x, v, work = state.x, state.v, 0.0
        reuse = self._reuses(system)
        a = p = None
        for i, b in enumerate(self.kick):
            if self.drift[i] != 0.0:
                x = x + (dt * self.drift[i]) * v
            if i == 0 and reuse:
                a, p = state.memory
                v = v + (dt * b) * a
            elif reuse and i == self.kick.size - 1:
                a, p = system.rhs(x, v)
                v = v + (dt * b) * a
            else:
                v, p = self._kick(system, x, v, dt * b)
            work += dt * b * p
        if self.drift[-1] != 0.0:
            x = x + (dt * self.drift[-1]) * v
        return State(x, v, (a, p) if reuse else (), state.dissipated + work)

    def oscillator_matrix(self, h_omega: np.ndarray, h_gamma: np.ndarray) -> np.ndarray:
        """Product of the drift and kick matrices on ``(x, dt v)`` for ``x'' = -w^2 x - gamma x'``.

        Drift ``a``: ``[[1, a], [0, 1]]``. A kick ``b`` steps ``u' = -g u - w2 x`` (x fixed)
        over ``b`` with its Runge-Kutta method ``(A_k, b_k)``: ``u -> R(z) u - b w2 S(z) x``
        with ``z = -b g``, ``S(z) = b_k^T (I - z A_k)^-1 1`` and ``R = 1 + z S`` — for
        ``g = 0`` the plain kick ``[[1, 0], [-b w2, 1]]``.
        """
        w2, g = np.broadcast_arrays(np.square(np.asarray(h_omega, dtype=float)),
                                    np.asarray(h_gamma, dtype=float))
        eye = np.broadcast_to(np.eye(2), w2.shape + (2, 2))
        rk = self.kick_method
        coef = rk.polynomials.N_float[1:]  # S(z) = (R(z) - 1) / z for the explicit tableau: R = N
        M = eye.copy()

        def drift(a: float):
            D = eye.copy()
            D[..., 0, 1] = a
            return D

        for i, b in enumerate(self.kick):
            M = drift(self.drift[i]) @ M
            S = np.polynomial.polynomial.polyval(-b * g, coef)
            K = eye.copy()
            K[..., 1, 0] = -b * w2 * S
            K[..., 1, 1] = 1.0 - b * g * S
            M = K @ M
        return drift(self.drift[-1]) @ M
