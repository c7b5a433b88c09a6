"""Damped scenes: the energy ledger K + U + D is conserved to the method's order (fitted slope)."""

import numpy as np
import pytest

import mslab
from mslab.scenes.generators import chain, oscillator


def _slope(scene, method, dts, t_end):
    errors = []
    for dt in dts:
        tr = mslab.simulate(scene, method, dt=dt, t_end=t_end, save_every=10)
        errors.append(float(np.max(np.abs(tr.energy.total - tr.energy.total[0]))))
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0] if len(dts) > 1 else np.nan
    return slope, errors


#: symplectic Runge-Kutta methods conserve quadratic invariants: their ledger closes to round-off
QUADRATIC = [m for m in mslab.methods()
             if mslab.get_method(m).family == "implicit_rk" and mslab.get_method(m).symplectic]


#: ledger drifts below this say nothing about the order (round-off is ~1e-15 here)
FLOOR = 1e-12


@pytest.mark.parametrize("method", [m for m in mslab.methods() if m not in QUADRATIC])
def test_damped_oscillator_ledger_order(method):
    """The slope between the two finest steps (h w0 = 0.1 .. 0.0125) whose drift is above FLOOR.

    The drift is ``C h^p (1 + D h + ...)``: a fit over coarse steps reads low for a method
    with a large ``D`` (the 3/8-rule RK4: 3.87 over h = 0.02 .. 0.005 against a bound of
    3.85); the finest pair still far above round-off sees ``p``.
    """
    scene = oscillator(stiffness=4.0, gamma=0.4, displacement=0.3)
    order = mslab.get_method(method).order
    errors = []
    for dt in (0.05, 0.025, 0.0125, 0.00625):
        error = _slope(scene, method, [dt], 2.0)[1][0]
        if error < FLOOR:
            break
        errors.append(error)
    assert len(errors) >= 2, errors
    slope = float(np.log2(errors[-2] / errors[-1]))
    assert slope > order - 0.15, (slope, errors)  # at least the method's order (Heun: 3 on a linear problem)
    assert slope < order + 1.15


@pytest.mark.parametrize("method", QUADRATIC)
def test_symplectic_rk_keeps_the_ledger_of_a_linear_oscillator_exactly(method):
    """A quadratic invariant: implicit midpoint and Gauss book K + U + D to roundoff at any dt."""
    assert {"implicit_midpoint", "gauss2"} <= set(QUADRATIC)
    scene = oscillator(stiffness=4.0, gamma=0.4, displacement=0.3)
    tr = mslab.simulate(scene, method, dt=0.05, t_end=2.0)
    assert np.max(np.abs(tr.energy.total - tr.energy.total[0])) < 1e-13


@pytest.mark.parametrize("method", ["symplectic_euler", "symplectic_euler_x", "heun", "midpoint", "rk3",
                                    "rk4", "verlet", "leapfrog", "velocity_verlet", "implicit_euler_fp"])
def test_damped_chain_ledger_order(method):
    """Nonlinear chain with spring damping and air drag."""
    scene = chain(5, stiffness=200.0, gamma=0.2, damping=0.5)
    slope, errors = _slope(scene, method, [0.004, 0.002, 0.001], 1.0)
    order = mslab.get_method(method).order
    assert abs(slope - order) < 0.5, (slope, errors)
