"""Stability functions and oscillator maps, read from each method's own coefficients.

Two test problems (lecture notes, §2.6):

* **Dahlquist**, ``y' = lam y`` (lecture notes, eq. 29) with ``z = lam * dt``. A Runge-Kutta
  method maps ``y_n`` to ``R(z) y_n`` with ``R(z) = det(I - zA + z 1 b^T) / det(I - zA)``
  (forward Euler: ``R = 1 + z``, eq. 32 of the lecture notes), from the tableau that steps.
* **Oscillator**, ``x'' = -w^2 x - gamma x'``. Splittings and the two-step forms treat x
  and v differently and have no scalar ``R(z)``: one step is a linear map of the method's
  whole state, its *amplification matrix*. In the scaled variables ``(x, dt v, ...)`` it
  depends only on ``h_omega = dt w`` and ``h_gamma = dt gamma``; each family computes it
  from its coefficients (``Integrator.oscillator_matrix``).

For a method without a scalar ``R``, ``amplification(method, z)`` is defined through the real
oscillator whose first-order eigenvalues are ``z`` and ``conj(z)`` (``h_omega^2 = |z|^2``,
``h_gamma = -2 Re z``; a real ``z`` gives the critically damped oscillator with the double
eigenvalue ``z``): the eigenvalue of largest modulus of that oscillator's map. For a
Runge-Kutta method this definition gives ``|R(z)|`` again, so regions are comparable.
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import numpy as np

from mslab.integrators.base import Integrator, get_method
from mslab.state import State

if TYPE_CHECKING:
    import numpy.typing as npt
    import sympy


def tableau(method: str | Integrator) -> tuple[np.ndarray, np.ndarray] | None:
    """Butcher tableau ``(A, b)`` of a Runge-Kutta method (the arrays that step); None otherwise."""
    m = get_method(method)
    return (m.A, m.b) if "A" in m.coefficients else None


def amplification(method: str | Integrator, z: npt.ArrayLike) -> np.ndarray:
    """Amplification factor ``R(z)``, ``z = dt * lam``, for an array of complex z.

    Parameters
    ----------
    method : str or Integrator
    z : complex array_like, any shape

    Returns
    -------
    ndarray of complex, shape of z
        ``R(z)`` for Runge-Kutta methods (inf at a pole); for the others the eigenvalue of
        largest modulus of the map of the oscillator with eigenvalues ``z, conj(z)``.
    """
    m = get_method(method)
    z = np.asarray(z, dtype=complex)
    R = m.stability_function(z)
    if R is not None:
        return R
    mats = amplification_matrix(m, np.abs(z), -2.0 * z.real)
    mu = np.linalg.eigvals(mats.reshape((-1,) + mats.shape[-2:]))
    pick = np.take_along_axis(mu, np.argmax(np.abs(mu), axis=-1)[:, None], axis=-1)[:, 0]
    return pick.reshape(z.shape)


def amplification_sympy(method: str | Integrator) -> sympy.Expr:
    """Exact ``R(z)`` of a Runge-Kutta method as a sympy expression in ``z`` (:mod:`mslab.derive`).

    Raises TypeError for methods without a scalar ``R`` (use :func:`amplification_matrix`).
    """
    from mslab import derive

    m = get_method(method)
    if m.stability_function(np.zeros(1)) is None:
        raise TypeError(f"{m.name} is a partitioned method without a scalar R(z); "
                        "use amplification_matrix(method, h_omega, h_gamma)")
    return derive.stability_function(m)


def amplification_matrix(method: str | Integrator, h_omega: npt.ArrayLike,
                         h_gamma: npt.ArrayLike = 0.0) -> np.ndarray:
    """One-step map of a method on the damped oscillator ``x'' = -w^2 x - gamma x'``.

    Parameters
    ----------
    method : str or Integrator
    h_omega : array_like
        ``dt * w``.
    h_gamma : array_like, broadcast with ``h_omega``
        ``dt * gamma`` (gamma per unit mass).

    Returns
    -------
    ndarray, shape broadcast(h_omega, h_gamma) + (k, k)
        The map of the scaled state: ``k = 2``, ``(x, dt v)`` for one-step methods;
        ``k = 3`` for Verlet ``(x, dt v, x_prev)`` and leapfrog ``(x, dt v_half, dt^2 a_prev)``.
        For a Runge-Kutta tableau it is ``R(dt J)`` with ``dt J = [[0, 1], [-w2, -g]]``.
    """
    return get_method(method).oscillator_matrix(h_omega, h_gamma)


def spectral_radius(matrices: np.ndarray) -> np.ndarray:
    """Largest eigenvalue modulus of each matrix in a stack (..., k, k)."""
    return np.max(np.abs(np.linalg.eigvals(matrices)), axis=-1)


def region_grid(method: str | Integrator, re: np.ndarray, im: np.ndarray) -> np.ndarray:
    """``|R(re + i im)|`` on the grid ``meshgrid(re, im)``, shape (len(im), len(re))."""
    zr, zi = np.meshgrid(np.asarray(re, dtype=float), np.asarray(im, dtype=float))
    return np.abs(amplification(method, zr + 1j * zi))


def measured_amplification_matrix(method: str | Integrator, h_omega: float, h_gamma: float = 0.0,
                                  delta: float = 1e-2) -> np.ndarray:
    """Return the one-step map *measured* by running the real integrator on an oscillator scene.

    Independent of :func:`amplification_matrix`: a SceneBuilder scene (pinned anchor at
    ``x = -1``, one free unit mass at ``x = 0``, a 1D spring of rest length 1 and stiffness
    ``h_omega^2``, Damping ``h_gamma`` when > 0) is stepped with ``dt = 1`` by the method's
    own ``start``/``step`` from the equilibrium with one state component perturbed by
    ``delta`` at a time. The state components are x, v and every memory entry shaped like
    x; scalar memory entries (dissipated power) do not feed back and are left out. The
    spring stays longer than 0, so the map is exactly linear.

    Returns
    -------
    ndarray, shape (k, k)
        ``k = 2 + number of array memory entries``. Its non-zero eigenvalues equal those of
        :func:`amplification_matrix`.
    """
    from mslab.scenes.builder import SceneBuilder

    m = get_method(method)
    b = SceneBuilder(1)
    anchor = b.add_particle([-1.0], mass=1.0, pinned=True)
    p = b.add_particle([0.0], mass=1.0)
    b.add_spring(anchor, p, stiffness=float(h_omega) ** 2, rest_length=1.0)
    if h_gamma > 0:
        b.add_damping(float(h_gamma))
    scene = b.build("measured oscillator")
    system = scene.system
    eq = m.start(system, scene.state0, 1.0)
    slots = [i for i, item in enumerate(eq.memory)
             if isinstance(item, np.ndarray) and item.shape == eq.x.shape]

    def flat(state: State) -> np.ndarray:
        return np.array([state.x[p, 0], state.v[p, 0]] + [state.memory[i][p, 0] for i in slots])

    def perturbed(j: int) -> State:
        x, v = eq.x.copy(), eq.v.copy()
        memory = list(eq.memory)
        if j == 0:
            x[p, 0] += delta
        elif j == 1:
            v[p, 0] += delta
        else:
            item = memory[slots[j - 2]].copy()
            item[p, 0] += delta
            memory[slots[j - 2]] = item
        return State(x, v, tuple(memory), 0.0)

    base = flat(m.step(system, eq, 1.0))
    k = 2 + len(slots)
    return np.stack([(flat(m.step(system, perturbed(j), 1.0)) - base) / delta for j in range(k)], axis=1)


def same_spectrum(m1: np.ndarray, m2: np.ndarray, atol: float = 1e-9) -> float:
    """Largest distance between the eigenvalues of two maps, ignoring eigenvalues below ``atol``.

    Returns inf when the numbers of non-negligible eigenvalues differ.
    """
    e1 = [e for e in np.linalg.eigvals(m1) if abs(e) > atol]
    e2 = [e for e in np.linalg.eigvals(m2) if abs(e) > atol]
    if len(e1) != len(e2):
        return np.inf
    if not e1:
        return 0.0
    return min(max(abs(a - b) for a, b in zip(e1, perm, strict=True)) for perm in itertools.permutations(e2))
