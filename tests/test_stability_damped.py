"""max_stable_dt on damped scenes for methods without a scalar R(z): pure drag and coupled modes.

Independent truths: the method's own oscillator map with ``h_omega = 0`` (a free particle
under drag is that oscillator), a hand-written leapfrog matrix of the whole linearised rope,
and real runs of the rope of lesson 00 just below and just above the predicted limit.
"""

import warnings

import numpy as np
import pytest

import mslab
from mslab import stability as st

NO_SCALAR_R = ["symplectic_euler", "symplectic_euler_x", "verlet", "leapfrog", "velocity_verlet",
               "forest_ruth", "yoshida6"]


def drag_particle(mass: float = 0.02, gamma: float = 0.5) -> mslab.Scene:
    b = mslab.SceneBuilder(dim=2)
    b.add_particle([0.0, 0.0], mass=mass, velocity=[0.3, -0.1])
    b.add_damping(gamma=gamma)
    return b.build("drag only")


def drag_limit_of_map(method: str) -> float:
    """Largest ``h_gamma`` with rho(amplification_matrix(method, 0, h_gamma)) <= 1, by bisection."""
    def stable(hg: float) -> bool:
        return st.spectral_radius(st.amplification_matrix(method, 0.0, hg)) <= 1.0 + 1e-10

    lo, hi = 1e-3, 1e-3
    while stable(hi):
        lo, hi = hi, 2 * hi
    while hi - lo > 1e-12:
        lo, hi = ((lo + hi) / 2, hi) if stable((lo + hi) / 2) else (lo, (lo + hi) / 2)
    return lo


@pytest.mark.parametrize("method", NO_SCALAR_R)
def test_free_particle_under_drag_gets_the_pure_drag_limit(method):
    # eigenvalues 0 and -gamma/m: the oscillator with h_omega = 0, h_gamma = dt gamma / m
    # (the old code read -gamma/m as a critically damped oscillator: leapfrog 0.472 m/gamma)
    expected = drag_limit_of_map(method) * 0.02 / 0.5
    assert st.max_stable_dt(drag_particle(), method) == pytest.approx(expected, rel=1e-8)


def test_leapfrog_pure_drag_limit_is_h_gamma_over_m_equal_1():
    # leapfrog on v' = -g v: char. polynomial mu^2 - (1 - 3/2 g h) mu - g h / 2, root -1 at g h = 1
    assert st.max_stable_dt(drag_particle(0.02, 0.5), "leapfrog") == pytest.approx(0.04, rel=1e-8)


def rope(n: int, gamma: float = 0.5, M: float = 0.1, L: float = 1.0) -> mslab.Scene:
    """Lesson 00's tuned rope: lumped masses, stretch 2 % under its own weight, drag gamma."""
    k = (n - 1) * M * 9.81 / (2 * 0.02 * L)
    b = mslab.SceneBuilder(dim=2)
    for i in range(n):
        b.add_particle([0.0, -L * i / (n - 1)], mass=M / (n - 1) * (0.5 if i in (0, n - 1) else 1.0),
                       pinned=(i == 0))
    for i in range(n - 1):
        b.add_spring(i, i + 1, stiffness=k)
    b.add_gravity([0.0, -9.81])
    b.add_damping(gamma=gamma)
    return b.build("rope")


def rope_leapfrog_rho(n: int, h: float, gamma: float = 0.5, M: float = 0.1) -> float:
    """Spectral radius of leapfrog's map on the linearised rope, written out by hand.

    At the start every spring has its rest length: sideways no stiffness, lengthwise the
    chain; drag gamma on every point. State (x, v_half, a_prev): x1 = x + h v_half,
    a = A x1 + B (v_half + h/2 a_prev), v_half1 = v_half + h a.
    """
    k = (n - 1) * M * 9.81 / (2 * 0.02)
    m = np.full(n - 1, M / (n - 1))
    m[-1] *= 0.5
    chain = np.diag(np.full(n - 1, -2 * k)) + np.diag(np.full(n - 2, k), 1) + np.diag(np.full(n - 2, k), -1)
    chain[-1, -1] = -k
    N = 2 * (n - 1)
    A = np.zeros((N, N))
    A[n - 1:, n - 1:] = chain / m[:, None]
    B = -gamma * np.diag(np.concatenate([1 / m, 1 / m]))
    eye, zero = np.eye(N), np.zeros((N, N))
    mat = np.block([[eye, h * eye, zero], [h * A, eye + h * (h * A + B), h * h / 2 * B],
                    [A, h * A + B, h / 2 * B]])
    return float(np.max(np.abs(np.linalg.eigvals(mat))))


@pytest.mark.parametrize("n", [6, 11])
def test_damped_rope_limit_is_where_the_hand_written_leapfrog_map_turns_unstable(n):
    limit = st.max_stable_dt(rope(n), "leapfrog")
    assert rope_leapfrog_rho(n, limit * (1 - 1e-6)) <= 1 + 1e-9
    assert rope_leapfrog_rho(n, limit * (1 + 1e-6)) > 1 + 1e-9


def speeds(dt: float, steps: int = 2000) -> tuple[float, float]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", mslab.StabilityWarning)
        tr = mslab.simulate(rope(6), "leapfrog", dt=dt, t_end=steps * dt, save_every=steps // 2,
                            energy_blowup=np.inf, blowup=1e12)
    return float(np.max(np.abs(tr.v[1]))), float(np.max(np.abs(tr.v[-1])))


def test_lesson00_damped_rope_settles_below_the_limit_and_grows_above():
    # the old prediction, 9.44 ms, was 8 % below the true limit (10.32 ms)
    limit = st.max_stable_dt(rope(6), "leapfrog")
    assert 10.2e-3 < limit < 10.4e-3
    assert speeds(0.98 * limit)[1] < 1e-9                 # at rest after 2000 steps
    assert min(speeds(1.02 * limit)) > 0.1                 # still moving at m/s scale (grown, saturated)


@pytest.mark.parametrize("method", NO_SCALAR_R)
def test_step_map_of_one_oscillator_has_the_oscillator_matrix_spectrum(method):
    A, B = np.array([[-0.7]]), np.array([[-0.3]])
    whole = st.scenes.step_map(method, A, B, 1.0)
    assert st.same_spectrum(whole, st.amplification_matrix(method, np.sqrt(0.7), 0.3), atol=1e-12) < 1e-10


def test_a_step_that_needs_more_than_rhs_keeps_the_per_eigenvalue_reading():
    from mslab.integrators.families.two_step import Leapfrog

    class MassReadingLeapfrog(Leapfrog):
        def step(self, system, state, dt):
            assert system.mass is not None        # the linear stand-in has no masses
            return super().step(system, state, dt)

    m = MassReadingLeapfrog("mass_reading_leapfrog", 2, mslab.get_method("velocity_verlet"))
    scene = drag_particle()
    # per eigenvalue: -gamma/m read as critically damped, leapfrog's real interval 0.4721
    assert st.max_stable_dt(scene, m) == pytest.approx(-st.real_interval("leapfrog") * 0.02 / 0.5, rel=1e-6)
