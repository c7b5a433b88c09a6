"""Fixed-point iteration beyond its contraction limit: a clear failure; Newton converges there."""

import numpy as np
import pytest

import mslab
from mslab import stability as st
from mslab.scenes.generators import chain, oscillator


def test_contraction_limit_is_one_over_the_largest_eigenvalue():
    scene = oscillator(stiffness=1e4, displacement=0.1)  # w = 100
    assert st.contraction_dt(scene) == pytest.approx(0.01)
    assert st.max_stable_dt(scene, "implicit_euler_fp") == pytest.approx(0.01)
    assert st.max_stable_dt(scene, "implicit_euler") == np.inf


@pytest.mark.parametrize("factor", [1.5, 4.0])
def test_fixed_point_beyond_contraction_fails_clearly_newton_converges(factor):
    scene = chain(6, stiffness=1e3)
    dt = factor * st.contraction_dt(scene)
    with pytest.raises(mslab.ConvergenceError) as info:
        mslab.simulate(scene, "implicit_euler_fp", dt=dt, t_end=20 * dt)
    err = info.value
    text = str(err)
    assert err.method == "implicit_euler_fp" and err.step >= 1 and err.dt == dt
    for part in ("implicit_euler_fp", f"step {err.step}", f"dt = {dt:g}", "Newton", "implicit_euler"):
        assert part in text, (part, text)
    tr = mslab.simulate(scene, "implicit_euler", dt=dt, t_end=20 * dt)
    assert tr.complete and np.all(np.isfinite(tr.x))


def test_below_contraction_fixed_point_equals_newton():
    scene = chain(6, stiffness=1e3)
    dt = 0.3 * st.contraction_dt(scene)
    fp = mslab.simulate(scene, "implicit_euler_fp", dt=dt, t_end=30 * dt)
    newton = mslab.simulate(scene, "implicit_euler", dt=dt, t_end=30 * dt)
    np.testing.assert_allclose(fp.x, newton.x, atol=1e-8)
