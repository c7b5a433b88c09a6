"""Exercise 10: the cheapest method for an error target (lesson 07; lecture notes, eqs. 16-20)."""

import math

import numpy as np


def fit_error_model(dts, errors):
    """Least-squares fit of ``log e = log C + p log h``.

    Parameters
    ----------
    dts, errors : sequence of float, same length (at least 2)

    Returns
    -------
    C, p : float
    """
    # BEGIN SOLUTION
    p, log_c = np.polyfit(np.log(np.asarray(dts, dtype=float)), np.log(np.asarray(errors, dtype=float)), 1)
    return float(math.exp(log_c)), float(p)
    # END SOLUTION


def step_for_target(C, p, target):
    """The step ``h`` with ``C h^p = target``.

    Returns
    -------
    h : float
    """
    # BEGIN SOLUTION
    return float((target / C) ** (1.0 / p))
    # END SOLUTION


def predicted_cost(h, t_end, evals_per_step, start_evals=0):
    """Steps and force evaluations of a run over ``t_end`` with a step of at most ``h``.

    Returns
    -------
    n_steps, n_force : int
        ``ceil(t_end / h)`` and ``n_steps * evals_per_step + start_evals``.
    """
    # BEGIN SOLUTION
    n_steps = math.ceil(t_end / h)
    return int(n_steps), int(n_steps * evals_per_step + start_evals)
    # END SOLUTION


def cheapest(runs, target, t_end):
    """The method predicted to reach ``target`` with the fewest force evaluations.

    Parameters
    ----------
    runs : dict
        ``{name: {"dts": [...], "errors": [...], "evals_per_step": int, "start_evals": int}}``.
    target : float
    t_end : float

    Returns
    -------
    name : str
    n_steps, n_force : int
    """
    # BEGIN SOLUTION
    best = None
    for name, run in runs.items():
        C, p = fit_error_model(run["dts"], run["errors"])
        n_steps, n_force = predicted_cost(step_for_target(C, p, target), t_end, run["evals_per_step"],
                                          run["start_evals"])
        if best is None or n_force < best[2]:
            best = (name, n_steps, n_force)
    return best
    # END SOLUTION
