"""Accuracy versus cost: convergence orders, work-precision records and energy drift.

Three experiments answer "what does accuracy cost?" for any scene and any method:

* :func:`convergence` -- the error at ``t_end`` for a sweep of steps ``dt`` and the
  observed order ``p`` (least-squares slope of ``log error`` against ``log dt``); a
  method of order ``p`` has global error ``O(dt^p)`` (local error ``O(dt^(p+1))``).
* :func:`work_precision` -- one flat record per (method, dt): error, counted work
  (force evaluations, Jacobians, linear solves) and wall time; with scipy's
  ``solve_ivp`` (RK45, DOP853, Radau, BDF) over a tolerance sweep on the same forces
  as reference curves (:func:`scipy_records`).
* :func:`energy_drift` -- the relative error of the energy ledger ``K + U + D`` over a
  long run, its drift rate and a bounded-versus-drifting verdict.

Decisions
---------
**Error.** ``error`` is the max-norm of the final-state error over positions and
velocities, ``max(max|x - x_ref|, max|v - v_ref|)`` at ``t_end``; ``error_rms`` is the
root mean square of the same differences over every saved time (about ``n_save`` of
them, always including ``t_end``).

**Reference.** The scene's closed form ``scene.exact(t)`` where it has one (the
oscillators); otherwise scipy's ``solve_ivp(DOP853)`` with ``rtol = atol = 1e-12`` on the
first-order system ``y = (x, v)``, ``y' = (v, a(x, v))`` built from the very same
``scene.system.acceleration`` (pinned particles have zero acceleration and stay put).
The reference is cached per scene object and ``t_end``.

**Timing** follows DiffEqDevTools: a run that computes the error and warms up (imports,
compiled kernels, caches), then timed runs that compute nothing else, repeated until
``repeats`` runs or a ``budget`` of seconds is used (at least one); the record keeps the
minimum. When the error runs happened in worker processes (``jobs > 1``), the calling
process first makes one untimed warm-up run per method. mslab runs are timed by
``simulate``'s own ``stats.wall_time`` (stepping only), scipy runs around ``solve_ivp``.

**Parallel sweeps** (``jobs > 1``) run only the error runs in a process pool (their
results, counts included, do not depend on the machine's load). The timing runs always
run one after the other in the calling process, so no timing shares the machine with
another run of the sweep.

**Failures.** A (method, dt) that blows up (:class:`~mslab.errors.InstabilityError`) or
whose implicit iteration fails (:class:`~mslab.errors.ConvergenceError`) gives a record
with ``ok = False``, ``error = error_rms = inf``, ``wall_time = nan`` and the message in
``failure``; the sweep goes on.
"""

from mslab.precision.convergence import (
    ROUNDOFF_FLOOR,
    Convergence,
    convergence,
    error_ceiling,
    fit_order,
    fitted_orders,
)
from mslab.precision.drift import DRIFT_FLOOR, DRIFT_GROWTH, DRIFT_TREND, Drift, drift_verdict, energy_drift
from mslab.precision.reference import Reference, reference_solution
from mslab.precision.runs import whole_dts
from mslab.precision.work_precision import SCIPY_METHODS, SCIPY_RTOLS, scipy_records, work_precision

__all__ = ["DRIFT_FLOOR", "DRIFT_GROWTH", "DRIFT_TREND", "ROUNDOFF_FLOOR", "SCIPY_METHODS", "SCIPY_RTOLS",
           "Convergence", "Drift", "Reference", "convergence", "drift_verdict", "energy_drift",
           "error_ceiling", "fit_order", "fitted_orders", "reference_solution", "scipy_records",
           "whole_dts", "work_precision"]
