"""Implicit Euler's kept factorisations and options, as a run sees them (an outside check's findings).

* A run starts clean: the same ``simulate`` call twice on one scene gives bitwise the same
  trajectory and counters (the stage solvers kept on a System are dropped at a run's start).
* The CG convergence model never predicts CG with factors of another pattern (an infinite
  change) and is not refitted by a CG that measured no rate (negative curvature).
* ``newton_hessian="clamped"``: refused where it would be ignored; the default backend takes
  the compiled path it needs.
"""

from __future__ import annotations

import numpy as np
import pytest

import mslab
from mslab.integrators.newton import factor, linear, newton_matrix
from mslab.scenes.generators import cloth


def test_the_same_run_twice_is_the_same_run():
    scene = cloth(20, 20, gamma=0.01)
    runs = [mslab.simulate(scene, "implicit_euler", dt=1 / 60, t_end=12 / 60, backend="numpy")
            for _ in range(2)]
    assert runs[0].stats.n_factor > 0 and runs[0].stats.n_iter > 0
    assert np.array_equal(runs[0].x, runs[1].x) and np.array_equal(runs[0].v, runs[1].v)
    for count in ("n_iter", "n_factor", "n_solve", "n_lin_iter", "n_force", "n_jac"):
        assert getattr(runs[0].stats, count) == getattr(runs[1].stats, count), count


def test_cg_model_refuses_factors_of_another_pattern_and_ignores_rateless_runs():
    solver = linear.StageSolver(cloth(12, 12).system, 0.01, "reuse")
    assert solver.predicted_cg_iterations(np.inf, 1e-3) == np.inf
    assert solver.predicted_cg_iterations(np.nan, 1e-3) == np.inf
    before = dict(solver.beta)
    solver.refit(np.inf, 0.5)  # another pattern: no rate for this model
    solver.refit(1e-2, 1.0)  # negative curvature: no rate
    solver.refit(1e-2, np.inf)
    assert solver.beta == before
    # a measured rate refits: the model then predicts that rate at that change
    solver.refit(1e-2, 0.5)
    predicted = solver.predicted_cg_iterations(1e-2, 1e-3)
    assert predicted == pytest.approx(np.log(1e-3) / np.log(0.5), rel=1e-9)


@pytest.mark.parametrize("kwargs", [dict(solver="fixed_point"), dict(A=[[0.25, -0.0387], [0.5387, 0.25]],
                                                                        b=[0.5, 0.5])])
def test_clamped_matrix_is_refused_where_it_would_be_ignored(kwargs):
    A = kwargs.pop("A", [[1]])
    b = kwargs.pop("b", [1])
    with pytest.raises(ValueError, match="clamped"):
        mslab.ImplicitRK(A, b, newton_hessian="clamped", **kwargs)


def test_clamped_matrix_runs_on_the_default_backend():
    """A short run that ``auto`` would step in numpy takes the compiled path the option needs."""
    scene = cloth(10, 10, gamma=0.01)
    clamped = mslab.ImplicitRK([[1]], [1], name="implicit_euler_clamped", order=1, newton_hessian="clamped")
    exact = mslab.simulate(scene, "implicit_euler", dt=1 / 60, t_end=3 / 60, backend="numpy")
    run = mslab.simulate(scene, clamped, dt=1 / 60, t_end=3 / 60)
    assert np.abs(run.x - exact.x).max() < 1e-9


def _textbook_newton(system, state, dt, rtol=1e-10):
    """Implicit Euler by plain Newton: full steps, ``spsolve`` of ``I - h M^-1 (h K + D)`` each iteration."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    minv = sp.diags(np.repeat(system.inv_mass, system.dim))
    eye = sp.identity(state.x.size, format="csc")
    v = state.v.copy()
    for _ in range(30):
        x = state.x + dt * v
        g = v - state.v - dt * system.acceleration(x, v)
        if np.abs(g).max() <= rtol * (1.0 + np.abs(state.v).max()):
            return x
        K, D = system.jacobians(x, v)
        v = v + spla.spsolve((eye - dt * (minv @ (dt * K + D))).tocsc(), -g.ravel()).reshape(v.shape)
    raise AssertionError("plain Newton did not converge")


def test_a_root_at_a_saddle_of_the_objective_is_reached(monkeypatch):
    """A buckling 40 x 40 cloth at dt = 1/30: at steps 7 and 8 implicit Euler's root is a saddle of
    the objective (its Newton matrix is indefinite there), which shifted, minimising steps only
    crawl towards (the run used to stop after 200 iterations). After STALLED such steps Newton's
    own step of the indefinite matrix reaches the root plain Newton finds."""
    scene = cloth(40, 40, gamma=0.01)
    system, state, dt = scene.system, scene.state0, 1 / 30
    method = mslab.get_method("implicit_euler")
    plain = []
    real = linear.StageSolver.indefinite_direction
    monkeypatch.setattr(linear.StageSolver, "indefinite_direction",
                        lambda self, r: plain.append(1) or real(self, r))
    checked = 0
    for _ in range(8):
        before = len(plain)
        new = method.step(system, state, dt)
        if len(plain) > before:
            assert np.abs(new.x - _textbook_newton(system, state, dt)).max() < 1e-9
            K, D = system.jacobians(new.x, new.v)
            free = np.repeat(~system.pinned, 3)
            A = newton_matrix.newton_matrix(K, D, np.repeat(system.mass, 3), free, dt)
            assert factor.Factor(A, system.counters).n_negative > 0  # a saddle, not a minimum
            checked += 1
        state = new
    assert checked >= 1
