"""The explicit Runge-Kutta methods: forward Euler, Heun, midpoint, Kutta's RK3, classical RK4."""

from fractions import Fraction as Fr

from mslab.integrators.base import register
from mslab.integrators.families.runge_kutta import ExplicitRK

half, sixth, third = Fr(1, 2), Fr(1, 6), Fr(1, 3)

euler = register(ExplicitRK(
    [[0]], [1], name="euler", order=1,
    doc="""Forward (explicit) Euler, eq. 6 of the lecture notes.

    ``x_{n+1} = x_n + h v_n``,  ``v_{n+1} = v_n + h a(x_n, v_n)``.

    Order 1 (Taylor series cut after the first derivative, local error O(h^2)); one force
    evaluation per step. Stability: ``R(z) = 1 + z``, stable for ``-2 < h lambda < 0`` on
    real lambda (lecture notes, eq. 32) and *never* for an undamped oscillator (|R(i w h)| > 1):
    its energy grows every step. Tableau: ``A = [[0]], b = [1]``.
    """))

heun = register(ExplicitRK(
    [[0, 0], [1, 0]], [half, half], name="heun", order=2,
    doc="""Heun's method (explicit trapezoidal rule, improved Euler), eqs. 11-15 of the lecture notes.

    Predictor ``~y = y_n + h F(y_n)`` (an Euler step), then
    ``y_{n+1} = y_n + h/2 (F(y_n) + F(~y))``: the average of the slopes at both ends.

    Order 2; two force evaluations per step. ``R(z) = 1 + z + z^2/2``.
    Tableau: ``A = [[0, 0], [1, 0]], b = [1/2, 1/2]``.
    """))

midpoint = register(ExplicitRK(
    [[0, 0], [half, 0]], [0, 1], name="midpoint", order=2,
    doc="""Explicit midpoint method (modified Euler), §2.5. of the lecture notes

    Half an Euler step to ``y_{n+1/2} = y_n + h/2 F(y_n)``, then the whole step with the
    slope there: ``y_{n+1} = y_n + h F(y_{n+1/2})``.

    Order 2; two force evaluations per step (as Heun). ``R(z) = 1 + z + z^2/2`` (as Heun).
    Tableau: ``A = [[0, 0], [1/2, 0]], b = [0, 1]``.
    """))

rk3 = register(ExplicitRK(
    [[0, 0, 0], [half, 0, 0], [-1, 2, 0]], [sixth, Fr(2, 3), sixth], name="rk3", order=3,
    doc="""Kutta's third-order method (beyond the course).

    ``K1 = F(y_n)``, ``K2 = F(y_n + h/2 K1)``, ``K3 = F(y_n - h K1 + 2h K2)``,
    ``y_{n+1} = y_n + h/6 (K1 + 4 K2 + K3)``.

    Order 3; three force evaluations per step. ``R(z) = 1 + z + z^2/2 + z^3/6``.
    """))

rk4 = register(ExplicitRK(
    [[0, 0, 0, 0], [half, 0, 0, 0], [0, half, 0, 0], [0, 0, 1, 0]], [sixth, third, third, sixth],
    name="rk4", order=4,
    doc="""Classical Runge-Kutta method, eqs. 16-20 of the lecture notes.

    ``K1 = F(y_n)``, ``K2 = F(y_n + h/2 K1)``, ``K3 = F(y_n + h/2 K2)``,
    ``K4 = F(y_n + h K3)``, ``y_{n+1} = y_n + h/6 (K1 + 2 K2 + 2 K3 + K4)``.
    (The fourth stage is at ``t + h``; eq. 19 of the lecture notes writes ``t``.)

    Order 4; four force evaluations per step. ``R(z) = sum_{k<=4} z^k / k!``; real
    stability interval about [-2.785, 0], imaginary about |y| <= 2.828.
    """))

rk6 = register(ExplicitRK(
    [[0, 0, 0, 0, 0, 0, 0],
     [Fr(1, 3), 0, 0, 0, 0, 0, 0],
     [0, Fr(2, 3), 0, 0, 0, 0, 0],
     [Fr(1, 12), Fr(1, 3), Fr(-1, 12), 0, 0, 0, 0],
     [Fr(-1, 16), Fr(9, 8), Fr(-3, 16), Fr(-3, 8), 0, 0, 0],
     [0, Fr(9, 8), Fr(-3, 8), Fr(-3, 4), Fr(1, 2), 0, 0],
     [Fr(9, 44), Fr(-9, 11), Fr(63, 44), Fr(18, 11), 0, Fr(-16, 11), 0]],
    [Fr(11, 120), 0, Fr(27, 40), Fr(27, 40), Fr(-4, 15), Fr(-4, 15), Fr(11, 120)],
    name="rk6", order=6,
    doc="""Butcher's seven-stage method of order 6 (beyond the course).

    Seven force evaluations per step, the fewest an explicit order-6 tableau can have.
    Splittings of order 5 or 6 integrate their kicks with it when forces depend on
    velocity. Reference: J. C. Butcher, J. Austral. Math. Soc. 4 (1964) 179; Hairer,
    Norsett & Wanner, Solving ODEs I, II.5 (eq. 5.19 family).
    """))
