"""Exercise 09: the ledger K + U + D and a method's drift (lesson 06; lecture notes, eqs. 1, 23, 27)."""

import numpy as np


def kinetic_energy(v, problem):
    """``K = sum_i m_i |v_i|^2 / 2`` over the free particles.

    Parameters
    ----------
    v : ndarray, shape (n_particles, dim)
    problem : has ``mass`` (n_particles,) and ``pinned`` (n_particles,) of bool

    Returns
    -------
    K : float
    """
    # BEGIN SOLUTION
    v = np.asarray(v, dtype=float)
    free = ~np.asarray(problem.pinned)
    return float(0.5 * np.sum(problem.mass[free, None] * v[free] ** 2))
    # END SOLUTION


def potential_energy(x, problem):
    """Springs ``sum_q k_q (l_q - L_q)^2 / 2`` plus gravity ``-sum_i m_i g . x_i`` (all particles).

    Parameters
    ----------
    x : ndarray, shape (n_particles, dim)
    problem : has ``springs`` (n_springs, 2), ``stiffness``, ``rest_length`` (n_springs,),
        ``mass`` (n_particles,) and ``gravity`` (dim,)

    Returns
    -------
    U : float
    """
    # BEGIN SOLUTION
    x = np.asarray(x, dtype=float)
    i, j = problem.springs[:, 0], problem.springs[:, 1]
    length = np.linalg.norm(x[i] - x[j], axis=1)
    springs = 0.5 * np.sum(problem.stiffness * (length - problem.rest_length) ** 2)
    gravity = -np.sum(problem.mass[:, None] * problem.gravity[None, :] * x)
    return float(springs + gravity)
    # END SOLUTION


def ledger(xs, vs, problem, dt):
    """The ledger of a run saved at every step: arrays ``K``, ``U``, ``D``.

    ``D_0 = 0``, ``D_{n+1} = D_n + dt/2 (P_n + P_{n+1})`` with the drag power
    ``P = gamma sum_free |v|^2`` (``problem.gamma``).

    Parameters
    ----------
    xs, vs : ndarray, shape (n_samples, n_particles, dim)
    problem : as above, plus ``gamma`` (float)
    dt : float

    Returns
    -------
    K, U, D : ndarray, shape (n_samples,)
    """
    # BEGIN SOLUTION
    xs, vs = np.asarray(xs, dtype=float), np.asarray(vs, dtype=float)
    K = np.array([kinetic_energy(v, problem) for v in vs])
    U = np.array([potential_energy(x, problem) for x in xs])
    free = ~np.asarray(problem.pinned)
    P = problem.gamma * np.sum(vs[:, free] ** 2, axis=(1, 2))
    D = np.concatenate([[0.0], np.cumsum(0.5 * dt * (P[:-1] + P[1:]))])
    return K, U, D
    # END SOLUTION


def band_and_drift(t, error):
    """The band (largest ``|error|``) and the drift rate (slope over the second half).

    Parameters
    ----------
    t, error : ndarray, shape (n,)

    Returns
    -------
    band, drift_rate : float
    """
    # BEGIN SOLUTION
    t, e = np.asarray(t, dtype=float), np.asarray(error, dtype=float)
    half = t >= t[0] + 0.5 * (t[-1] - t[0])
    slope = np.polyfit(t[half], e[half], 1)[0]
    return float(np.max(np.abs(e))), float(slope)
    # END SOLUTION


def verdict(t, error):
    """``"drifting"`` or ``"bounded"`` by the rule of lesson 06 (see the README).

    Returns
    -------
    verdict : str
    """
    # BEGIN SOLUTION
    t, e = np.asarray(t, dtype=float), np.asarray(error, dtype=float)
    span = t[-1] - t[0]
    early = np.max(np.abs(e[t <= t[0] + 0.25 * span]))
    late = np.max(np.abs(e[t >= t[-1] - 0.25 * span]))
    if max(early, late) <= 1e-11:
        return "bounded"
    half = t >= t[0] + 0.5 * span
    slope, intercept = np.polyfit(t[half], e[half], 1)
    scatter = np.std(e[half] - (intercept + slope * t[half]))
    moved = abs(slope) * (t[-1] - t[half][0])
    if moved > 3.0 * scatter or late > 10.0 * early:
        return "drifting"
    return "bounded"
    # END SOLUTION
