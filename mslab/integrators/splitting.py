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
no exact flow any more. Methods of order 1 kick explicitly with the current velocity,
``v' = v + b h a(x, v)`` (the course's symplectic Euler, seed eqs. 7-10, exactly). Methods
of order 2 and higher kick with the implicit midpoint rule in the velocity,
``v' = v + b h a(x, (v + v')/2)`` (x fixed), solved by ``p`` fixed-point corrections from
the explicit kick (``p`` the order; each correction is one counted force evaluation and
gains one power of h, so the kick is symmetric up to ``O(h^(p+2))``): every symmetric
composition (velocity Verlet, Forest-Ruth, Yoshida's methods) keeps its order on damped
scenes, at ``p + 1`` evaluations per kick. A fixed count keeps the work of a step
predictable (and the compiled loop's counts equal to the numpy loop's). The dissipated
power is booked at each kick's last velocity with weight ``b_i h``.
"""

from __future__ import annotations

import numpy as np

from mslab.integrators.base import Integrator
from mslab.integrators.coefficients import as_given, frozen
from mslab.state import State


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
    def __init__(self, drift, kick, name: str = "splitting", order: int = 0, doc: str | None = None):
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
        self.symmetric_kicks = self.order >= 2
        if doc:
            self.__doc__ = doc

    @property
    def compiled(self):
        """The generic compiled splitting loop over ``drift, kick``."""
        return "splitting", (self.drift, self.kick)

    def _reuses(self, system) -> bool:
        return self.fsal and not system.velocity_dependent

    def start(self, system, state: State, dt: float) -> State:
        """Evaluate the first acceleration once when it is reused from step to step."""
        if not self._reuses(system):
            return state
        a, p = system.rhs(state.x, state.v)
        return State(state.x, state.v, (a, p), state.dissipated)

    def _kick(self, system, x, v, bh: float):
        """``v' = v + bh a``: explicit, or the symmetric (implicit midpoint) kick."""
        a, p = system.rhs(x, v)
        new = v + bh * a
        if not (self.symmetric_kicks and system.velocity_dependent):
            return new, p
        for _ in range(self.order):  # each correction gains a power of h: the order is kept
            a, p = system.rhs(x, 0.5 * (v + new))
            new = v + bh * a
        return new, p

    def step(self, system, state: State, dt: float) -> State:
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

    def oscillator_matrix(self, h_omega, h_gamma):
        """Product of the drift and kick matrices on ``(x, dt v)`` for ``x'' = -w^2 x - gamma x'``.

        Drift ``a``: ``[[1, a], [0, 1]]``. Explicit kick ``b``: ``[[1, 0], [-b w2, 1 - b g]]``.
        Symmetric kick (order >= 2, ``g > 0``): ``u_0 = u + b (-w2 x - g u)``, then ``p``
        corrections ``u_(k+1) = u + b (-w2 x - g (u + u_k)/2)``, as the step does.
        """
        w2, g = np.broadcast_arrays(np.square(np.asarray(h_omega, dtype=float)),
                                    np.asarray(h_gamma, dtype=float))
        eye = np.broadcast_to(np.eye(2), w2.shape + (2, 2))
        M = eye.copy()

        def drift(a):
            D = eye.copy()
            D[..., 0, 1] = a
            return D

        for i, b in enumerate(self.kick):
            M = drift(self.drift[i]) @ M
            alpha, beta = -b * w2, 1.0 - b * g           # u' = alpha x + beta u
            if self.symmetric_kicks:                      # (with g = 0 the corrections change nothing)
                for _ in range(self.order):
                    alpha, beta = -b * w2 - 0.5 * b * g * alpha, 1.0 - 0.5 * b * g * (1.0 + beta)
            K = eye.copy()
            K[..., 1, 0] = alpha
            K[..., 1, 1] = beta
            M = K @ M
        return drift(self.drift[-1]) @ M
