"""Integrators: convergence orders on closed forms, counted work, immutability, registry."""

import numpy as np
import pytest

import mslab
from mslab.scenes import chain, oscillator

ALL = mslab.methods()


def final_error(scene, method, dt):
    tr = mslab.simulate(scene, method, dt=dt, save_every=10**9)
    xe, ve = scene.exact(tr.t[-1:])
    return max(np.abs(tr.x[-1] - xe[0]).max(), np.abs(tr.v[-1] - ve[0]).max())


def fitted_order(scene, method, dts):
    errors = [final_error(scene, method, dt) for dt in dts]
    return np.polyfit(np.log(dts), np.log(errors), 1)[0]


@pytest.mark.parametrize("gamma", [0.0, 0.4])
@pytest.mark.parametrize("method", ALL)
def test_convergence_order_on_oscillator(method, gamma):
    # w0 = 2, t_end = 1.5 (no zero crossing of the final error); dts in the asymptotic range
    scene = oscillator(stiffness=4.0, mass=1.0, gamma=gamma, displacement=0.3, velocity=0.2, t_end=1.5)
    order = mslab.get_method(method).order
    dts = [1.5 / n for n in (40, 80, 160, 320)] if order < 4 else [1.5 / n for n in (20, 40, 80, 160)]
    assert fitted_order(scene, method, dts) == pytest.approx(order, abs=0.2)


#: the ledger's round-off on the damped oscillator below (E ~ 0.2, up to 320 steps) is ~1e-15:
#: drifts below 1000 times that say nothing about the order
LEDGER_FLOOR = 1e-12


def ledger_slope(method) -> float:
    """Local slope of the ledger drift between the two finest steps (n = 40 .. 320) above the floor.

    The drift is ``C h^p (1 + D h + ...)``: a slope fitted over coarse steps is pulled down by
    ``D h`` (rk4: 3.83 over n = 40..160, the 3/8 rule 3.70). The finest pair of steps whose
    drift is still far above round-off sees ``p`` up to ``D h`` at ``h w0 = 0.0125``.
    """
    scene = oscillator(stiffness=4.0, gamma=0.5, displacement=0.3, t_end=2.0)
    kept = []
    for n in (40, 80, 160, 320):
        tr = mslab.simulate(scene, method, dt=2.0 / n)
        assert tr.energy.dissipated[-1] > 0.01  # damping really took energy out
        drift = float(np.abs(tr.energy.total - tr.energy.total[0]).max())
        if drift < LEDGER_FLOOR:
            break
        kept.append(drift)
    assert len(kept) >= 2, f"ledger drift below {LEDGER_FLOOR} already at n = 80: {kept}"
    return float(np.log2(kept[-2] / kept[-1]))


def check_ledger_order(method) -> None:
    """Assert that the ledger of ``method`` (a name or a method object) closes to its declared order."""
    if method in ("implicit_midpoint", "gauss2"):
        # it conserves quadratic invariants exactly: on a linear oscillator the ledger
        # (quadratic energy + dissipated work booked at the midpoint) closes to round-off
        scene = oscillator(stiffness=4.0, gamma=0.5, displacement=0.3, t_end=2.0)
        tr = mslab.simulate(scene, method, dt=2.0 / 80)
        assert np.abs(tr.energy.total - tr.energy.total[0]).max() < 1e-13
        return
    assert ledger_slope(method) >= mslab.get_method(method).order - 0.2


@pytest.mark.parametrize("method", ALL)
def test_ledger_total_conserved_to_method_order_with_damping(method):
    check_ledger_order(method)


@pytest.mark.parametrize("method", ALL)
def test_force_evaluations_are_counted_per_stage(method):
    scene = chain(6, dim=2, stiffness=50.0)
    integ = mslab.get_method(method)
    tr = mslab.simulate(scene, method, dt=1e-3, t_end=0.05)
    s = tr.stats
    assert s.steps == 50
    if integ.explicit:
        assert s.n_force == integ.n_stages * s.steps + integ.n_start
        assert s.n_jac == s.n_solve == s.n_iter == 0
    elif method == "implicit_euler_fp":
        assert s.n_force == s.n_iter and s.n_iter >= s.steps
    elif integ.family == "local_global":  # no Newton: a fixed number of sweeps, one factorisation per dt
        assert s.n_force == s.n_solve == s.n_iter == integ.iterations * s.steps
        assert s.n_jac == 0 and s.n_factor == 1
    elif integ.diagonally_implicit:  # Newton per stage: one evaluation per iteration + the converged check
        assert s.n_force == s.n_iter + integ.n_stages * s.steps
        implicit_stages = int(np.count_nonzero(np.diag(integ.A)))  # an explicit first stage solves nothing
        assert s.n_jac == s.n_solve == s.n_iter >= implicit_stages * s.steps
    else:  # Newton on all stages at once: each residual and each Jacobian evaluates every stage
        assert s.n_force == integ.n_stages * (s.n_iter + s.steps)
        assert s.n_jac == integ.n_stages * s.n_iter and s.n_solve == s.n_iter >= s.steps


@pytest.mark.parametrize("method", ALL)
def test_step_mutates_nothing_and_pinned_never_move(method):
    scene = chain(5, dim=3, stiffness=80.0, pin="both", gamma=0.1, damping=0.05)
    integ = mslab.get_method(method)
    system = scene.system
    state = integ.start(system, scene.state0, 1e-3)
    x0, v0 = state.x.copy(), state.v.copy()
    new = integ.step(system, state, 1e-3)
    np.testing.assert_array_equal(state.x, x0)
    np.testing.assert_array_equal(state.v, v0)
    assert new.x is not state.x
    tr = mslab.simulate(scene, method, dt=1e-3, t_end=0.2)
    pinned = tr.x[:, [0, 4]]
    np.testing.assert_array_equal(pinned, np.broadcast_to(scene.state0.x[[0, 4]], pinned.shape))
    assert np.abs(tr.x[-1, 2] - scene.state0.x[2]).max() > 1e-3  # the free ones did move


def test_registry_names_and_flags():
    assert mslab.methods()[:10] == list(mslab.COURSE_METHODS)
    assert set(ALL) >= {"rk3", "rk6", "velocity_verlet", "implicit_midpoint", "sdirk2", "gauss2",
                        "radau_iia2", "forest_ruth", "yoshida6"}
    assert mslab.get_method("symplectic-euler").name == "symplectic_euler"
    with pytest.raises(ValueError, match="did you mean 'rk4'"):
        mslab.get_method("rk44")
    symplectic = {m for m in ALL if mslab.get_method(m).symplectic}
    assert symplectic == {"symplectic_euler", "symplectic_euler_x", "verlet", "leapfrog",
                          "velocity_verlet", "implicit_midpoint", "gauss2", "forest_ruth", "yoshida6"}


def test_explicit_rk_accepts_any_tableau():
    # Ralston's second-order method: not registered, steps through the same code path
    ralston = mslab.ExplicitRK([[0, 0], [2 / 3, 0]], [1 / 4, 3 / 4], name="ralston", order=2)
    scene = oscillator(stiffness=4.0, displacement=0.3, velocity=0.2, t_end=1.5)
    assert fitted_order(scene, ralston, [1.5 / n for n in (40, 80, 160)]) == pytest.approx(2, abs=0.2)
    with pytest.raises(ValueError, match="strictly lower triangular"):
        mslab.ExplicitRK([[1.0]], [1.0])


def test_rk4_step_matches_hand_computed_stages():
    scene = oscillator(stiffness=1.0, displacement=0.5)
    integ = mslab.get_method("rk4")
    h = 0.1
    new = integ.step(scene.system, scene.state0, h)
    # linear oscillator u'' = -u: one RK4 step is the degree-4 Taylor polynomial of exp(hA)
    A = np.array([[0.0, 1.0], [-1.0, 0.0]])
    M = sum(np.linalg.matrix_power(h * A, k) / np.prod(range(1, k + 1)) for k in range(5))
    u = M @ np.array([0.5, 0.0])
    assert new.x[1, 0] - 1.0 == pytest.approx(u[0], rel=1e-13)
    assert new.v[1, 0] == pytest.approx(u[1], rel=1e-13)


def test_tableau_is_frozen():
    """The tableau that steps is the tableau that stability and derive read: no later edits."""
    rk4 = mslab.get_method("rk4")
    with pytest.raises(ValueError, match="read-only"):
        rk4.b[0] = 0.5
    A = np.array([[0.0, 0.0], [1.0, 0.0]])
    heun = mslab.ExplicitRK(A, [0.5, 0.5])
    A[1, 0] = 7.0  # the caller's array is copied, not shared
    assert heun.A[1, 0] == 1.0
