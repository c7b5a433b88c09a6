"""Verlet (two-step position form) and leapfrog (staggered velocities): adapters over a splitting.

Both produce the positions of velocity Verlet, the splitting ``drift = [0, 1, 0],
kick = [1/2, 1/2]`` (their ``splitting`` attribute; :mod:`mslab.derive` takes its order
from that splitting's coefficients and expands their own step), but carry a different
state between steps and so start differently and report velocities their own way, as
the course writes them (lecture notes, eqs. 21-26). Each keeps its documented start-up step and
second-order velocity estimate.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.base import Integrator
from mslab.state import State

if TYPE_CHECKING:
    from mslab.system import System


class _SplittingForm(Integrator):
    """What Verlet and leapfrog share: the splitting they equal and a compiled loop of their own."""

    symplectic = True
    n_start = 1
    #: the compiled loop of :mod:`mslab.fast` that steps this form
    loop: str = ""

    def __init__(self, name: str, order: int, splitting: Integrator):
        self.name, self.order, self.splitting = name, order, splitting

    @property
    def compiled(self) -> tuple[str, tuple]:
        """Return the compiled loop of this form (it needs no coefficient arrays)."""
        return self.loop, ()


class Verlet(_SplittingForm):
    """Position (Störmer) Verlet, eqs. 21-23 of the lecture notes.

    ``x_{n+1} = 2 x_n - x_{n-1} + h^2 a(x_n, v_n)``

    Start-up (one extra force evaluation): ``x_{-1} = x_0 - h v_0 + h^2/2 a_0`` (Taylor
    series backwards). Velocities are not part of the method; the state reports the
    second-order estimate ``v_{n+1} = (x_{n+1} - x_n)/h + h/2 a_n``, which is also the
    velocity fed to velocity-dependent forces. Dissipated work: two-step Adams-Bashforth
    ``D_{n+1} = D_n + h (3 P_n - P_{n-1}) / 2``.

    Order 2; one force evaluation per step; symplectic and time-reversible; stable for
    ``h w < 2`` on ``x'' = -w^2 x``. Memory: ``(x_{n-1}, P_{n-1})``.
    """

    family = "two_step"
    loop = "verlet"

    def start(self, system: System, state: State, dt: float) -> State:
        """``x_{-1}`` from the backward Taylor series."""
        a, p = system.rhs(state.x, state.v)
        x_prev = state.x - dt * state.v + (0.5 * dt * dt) * a
        return State(state.x, state.v, (x_prev, p), state.dissipated)

    def step(self, system: System, state: State, dt: float) -> State:
        """``x_{n+1} = 2 x_n - x_{n-1} + h^2 a_n`` and the velocity estimate."""
        x_prev, p_prev = state.memory
        a, p = system.rhs(state.x, state.v)
        x = 2.0 * state.x - x_prev + (dt * dt) * a
        v = (x - state.x) / dt + (0.5 * dt) * a
        return State(x, v, (state.x, p), state.dissipated + 0.5 * dt * (3.0 * p - p_prev))

    def oscillator_matrix(self, h_omega: np.ndarray, h_gamma: np.ndarray) -> np.ndarray:
        """Return the map of ``(x, dt v, x_prev)`` for ``x'' = -w^2 x - gamma x'`` (dt = 1)."""
        w2, g = np.broadcast_arrays(np.square(np.asarray(h_omega, dtype=float)),
                                    np.asarray(h_gamma, dtype=float))
        M = np.zeros(w2.shape + (3, 3))
        # a = -w2 x - g u;  x1 = 2x - xp + a;  u1 = x1 - x + a/2;  xp1 = x
        ax, au = -w2, -g
        M[..., 0, 0], M[..., 0, 1], M[..., 0, 2] = 2.0 + ax, au, -1.0
        M[..., 1, 0], M[..., 1, 1], M[..., 1, 2] = 1.0 + 1.5 * ax, 1.5 * au, -1.0
        M[..., 2, 0] = 1.0
        return M


class Leapfrog(_SplittingForm):
    """Leapfrog with staggered velocities at half steps, eqs. 24-26 of the lecture notes.

    ``x_{n+1} = x_n + h v_{n+1/2}``,  ``v_{n+3/2} = v_{n+1/2} + h a(x_{n+1}, v_{n+1})``

    Started by a half Euler step ``v_{1/2} = v_0 + h/2 a_0`` (one extra force
    evaluation). The reported velocity is synchronised with x:
    ``v_{n+1} = v_{n+1/2} + h/2 a_{n+1}``. Velocity-dependent forces get the predictor
    ``v_{n+1} ~ v_{n+1/2} + h/2 a_n``. Dissipated work: trapezoidal rule.

    Order 2; one force evaluation per step; symplectic; stable for ``h w < 2``.
    Algebraically the same positions as velocity Verlet. Memory: ``(v_{n+1/2}, a_n, P_n)``.
    """

    family = "staggered"
    loop = "leapfrog"

    def start(self, system: System, state: State, dt: float) -> State:
        """Take the half Euler step to ``v_{1/2}``."""
        a, p = system.rhs(state.x, state.v)
        return State(state.x, state.v, (state.v + (0.5 * dt) * a, a, p), state.dissipated)

    def step(self, system: System, state: State, dt: float) -> State:
        """Drift with ``v_{n+1/2}``, then kick to ``v_{n+3/2}``."""
        v_half, a_old, p_old = state.memory
        x = state.x + dt * v_half
        v_guess = v_half + (0.5 * dt) * a_old if system.velocity_dependent else v_half
        a, p = system.rhs(x, v_guess)
        v = v_half + (0.5 * dt) * a
        return State(x, v, (v_half + dt * a, a, p), state.dissipated + 0.5 * dt * (p_old + p))

    def oscillator_matrix(self, h_omega: np.ndarray, h_gamma: np.ndarray) -> np.ndarray:
        """Return the map of ``(x, dt v_half, dt^2 a_prev)`` for ``x'' = -w^2 x - gamma x'`` (dt = 1)."""
        w2, g = np.broadcast_arrays(np.square(np.asarray(h_omega, dtype=float)),
                                    np.asarray(h_gamma, dtype=float))
        M = np.zeros(w2.shape + (3, 3))
        # x1 = x + uh;  a = -w2 x1 - g (uh + ap/2);  uh1 = uh + a;  ap1 = a
        ax = -w2
        a_row = np.stack([ax, ax - g, -0.5 * g], axis=-1)   # a in terms of (x, uh, ap)
        M[..., 0, 0], M[..., 0, 1] = 1.0, 1.0
        M[..., 1, :] = a_row
        M[..., 1, 1] += 1.0
        M[..., 2, :] = a_row
        return M
