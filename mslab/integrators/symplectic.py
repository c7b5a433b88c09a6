"""Symplectic methods: the two symplectic Euler variants, Verlet, leapfrog, velocity Verlet.

Velocity-dependent forces (damping, damped springs, friction) break the Hamiltonian
structure these methods are made for. Where a method needs a velocity at a time where
it only knows positions, it uses a documented second-order estimate (see each class);
the methods then stay consistent and second order (tested on the damped oscillator),
though no longer exactly symplectic.
"""

from __future__ import annotations

from mslab.integrators.base import Integrator, register
from mslab.state import State


class SymplecticEuler(Integrator):
    """Symplectic Euler, velocity first (semi-implicit Euler), seed eqs. 9-10.

    ``v_{n+1} = v_n + h a(x_n, v_n)``,  ``x_{n+1} = x_n + h v_{n+1}``.

    Order 1; one force evaluation per step; symplectic. On ``x'' = -w^2 x`` stable for
    ``h w <= 2`` with bounded energy error. Other names: Euler-Cromer, semi-implicit Euler.
    """

    name = "symplectic_euler"
    order = 1
    symplectic = True
    course = True

    def step(self, system, state, dt):
        a, p = system.rhs(state.x, state.v)
        v = state.v + dt * a
        return State(state.x + dt * v, v, (), state.dissipated + dt * p)


class SymplecticEulerX(Integrator):
    """Symplectic Euler, position first, seed eqs. 7-8.

    ``x_{n+1} = x_n + h v_n``,  ``v_{n+1} = v_n + h a(x_{n+1}, v_n)``.

    Order 1; one force evaluation per step; symplectic (the adjoint of
    ``symplectic_euler``); same stability limit ``h w <= 2``.
    """

    name = "symplectic_euler_x"
    order = 1
    symplectic = True
    course = True

    def step(self, system, state, dt):
        x = state.x + dt * state.v
        a, p = system.rhs(x, state.v)
        return State(x, state.v + dt * a, (), state.dissipated + dt * p)


class Verlet(Integrator):
    """Position (Störmer) Verlet, seed eqs. 21-23.

    ``x_{n+1} = 2 x_n - x_{n-1} + h^2 a(x_n, v_n)``

    Start-up (one extra force evaluation): ``x_{-1} = x_0 - h v_0 + h^2/2 a_0`` (Taylor
    series backwards). Velocities are not part of the method; the state reports the
    second-order estimate ``v_{n+1} = (x_{n+1} - x_n)/h + h/2 a_n``, which is also the
    velocity fed to velocity-dependent forces. Dissipated work: two-step Adams-Bashforth
    ``D_{n+1} = D_n + h (3 P_n - P_{n-1}) / 2``.

    Order 2; one force evaluation per step; symplectic and time-reversible; stable for
    ``h w < 2`` on ``x'' = -w^2 x``. Memory: ``(x_{n-1}, P_{n-1})``.
    """

    name = "verlet"
    order = 2
    symplectic = True
    course = True
    n_start = 1

    def start(self, system, state, dt):
        a, p = system.rhs(state.x, state.v)
        x_prev = state.x - dt * state.v + (0.5 * dt * dt) * a
        return State(state.x, state.v, (x_prev, p), state.dissipated)

    def step(self, system, state, dt):
        x_prev, p_prev = state.memory
        a, p = system.rhs(state.x, state.v)
        x = 2.0 * state.x - x_prev + (dt * dt) * a
        v = (x - state.x) / dt + (0.5 * dt) * a
        return State(x, v, (state.x, p), state.dissipated + 0.5 * dt * (3.0 * p - p_prev))


class Leapfrog(Integrator):
    """Leapfrog with staggered velocities at half steps, seed eqs. 24-26.

    ``x_{n+1} = x_n + h v_{n+1/2}``,  ``v_{n+3/2} = v_{n+1/2} + h a(x_{n+1}, v_{n+1})``

    Started by a half Euler step ``v_{1/2} = v_0 + h/2 a_0`` (one extra force
    evaluation). The reported velocity is synchronised with x:
    ``v_{n+1} = v_{n+1/2} + h/2 a_{n+1}``. Velocity-dependent forces get the predictor
    ``v_{n+1} ~ v_{n+1/2} + h/2 a_n``. Dissipated work: trapezoidal rule.

    Order 2; one force evaluation per step; symplectic; stable for ``h w < 2``.
    Algebraically the same positions as velocity Verlet. Memory: ``(v_{n+1/2}, a_n, P_n)``.
    """

    name = "leapfrog"
    order = 2
    symplectic = True
    course = True
    n_start = 1

    def start(self, system, state, dt):
        a, p = system.rhs(state.x, state.v)
        return State(state.x, state.v, (state.v + (0.5 * dt) * a, a, p), state.dissipated)

    def step(self, system, state, dt):
        v_half, a_old, p_old = state.memory
        x = state.x + dt * v_half
        v_guess = v_half + (0.5 * dt) * a_old if system.velocity_dependent else v_half
        a, p = system.rhs(x, v_guess)
        v = v_half + (0.5 * dt) * a
        return State(x, v, (v_half + dt * a, a, p), state.dissipated + 0.5 * dt * (p_old + p))


class VelocityVerlet(Integrator):
    """Velocity Verlet (beyond the course's list).

    ``x_{n+1} = x_n + h v_n + h^2/2 a_n``,  ``v_{n+1} = v_n + h/2 (a_n + a_{n+1})``

    with ``a_{n+1} = a(x_{n+1}, v_n + h a_n)`` (an Euler predictor for the velocity, used
    only when forces depend on v). One start-up evaluation of ``a_0``.

    Order 2; one force evaluation per step; symplectic; stable for ``h w < 2``.
    Memory: ``(a_n, P_n)``.
    """

    name = "velocity_verlet"
    order = 2
    symplectic = True
    n_start = 1

    def start(self, system, state, dt):
        a, p = system.rhs(state.x, state.v)
        return State(state.x, state.v, (a, p), state.dissipated)

    def step(self, system, state, dt):
        a_old, p_old = state.memory
        x = state.x + dt * state.v + (0.5 * dt * dt) * a_old
        v_guess = state.v + dt * a_old
        a, p = system.rhs(x, v_guess)
        v = state.v + (0.5 * dt) * (a_old + a)
        return State(x, v, (a, p), state.dissipated + 0.5 * dt * (p_old + p))


symplectic_euler = register(SymplecticEuler())
symplectic_euler_x = register(SymplecticEulerX())
verlet = register(Verlet())
leapfrog = register(Leapfrog())
velocity_verlet = register(VelocityVerlet())
