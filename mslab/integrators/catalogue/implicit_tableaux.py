"""The implicit Runge-Kutta methods: implicit Euler (Newton and fixed point), implicit midpoint.

Beyond the course: Baraff-Witkin's linearised implicit Euler, SDIRK2, Gauss (2 stages) and
Radau IIA (2 stages).
"""

from fractions import Fraction as Fr
from math import sqrt

from mslab.integrators.base import register
from mslab.integrators.families.runge_kutta import ImplicitRK

implicit_euler = register(ImplicitRK(
    [[1]], [1], name="implicit_euler", order=1, solver="newton",
    doc="""Implicit (backward) Euler solved by Newton's method, eq. 27 of the lecture notes.

    ``x_{n+1} = x_n + h v_{n+1}``,  ``v_{n+1} = v_n + h a(x_{n+1}, v_{n+1})``

    Newton on the velocity: ``(I - h M^-1 (h K + D)) dv = -g(v)`` with
    ``g(v) = v - v_n - h a(x_n + h v, v)``, sparse direct solve, until
    ``max|g| <= 1e-10 (1 + max|v_n|)``. One Newton iteration from ``v = v_n`` is
    Baraff-Witkin's linearised implicit Euler. Tableau ``A = [[1]], b = [1]``.

    Order 1; per iteration one force evaluation, one Jacobian, one linear solve (plus one
    first residual evaluation, and one more for each halving of a Newton step by the
    backtracking line search, which only kinks such as contacts switching on need).
    ``R(z) = 1/(1 - z)``: A-stable (and L-stable); it damps oscillations numerically, so
    energy decays even without physical damping.
    """))

implicit_euler_fp = register(ImplicitRK(
    [[1]], [1], name="implicit_euler_fp", order=1, solver="fixed_point",
    doc="""Implicit Euler solved by fixed-point iteration, eq. 28 of the lecture notes.

    ``y^{(k+1)} = y_n + h F(y^{(k)})`` with ``y = (x, v)``, started from
    ``y^{(0)} = y_n`` (the first iterate is then a forward Euler step), until the change
    between iterates is below ``1e-10`` relative to the state's size.

    The iteration is a contraction only while ``h L < 1`` (for a spring of frequency
    w: roughly ``h w < 1``). When the iterates grow instead, the step fails with a message
    suggesting Newton's method (``implicit_euler``) or a smaller dt.

    Order 1; one force evaluation per iteration; same ``R(z) = 1/(1 - z)`` as Newton
    when it converges.
    """))

baraff_witkin = register(ImplicitRK(
    [[1]], [1], name="baraff_witkin", order=1, solver="linearised",
    doc="""Baraff and Witkin's linearised implicit Euler: one Newton step per time step (beyond the course).

    ``(M - h^2 K - h D) dv = h f(x_n + h v_n, v_n)``,  ``v_{n+1} = v_n + dv``,
    ``x_{n+1} = x_n + h v_{n+1}`` (``K, D`` the Jacobians at ``(x_n + h v_n, v_n)``): the first
    Newton iteration of implicit Euler (``implicit_euler``, eq. 27 of the lecture notes) from
    ``v = v_n``, whose position is ``x_n + h v_n``, without the further iterations and without a
    convergence test. Baraff and Witkin write the right side ``h (f(x_n, v_n) + h K v_n)`` with
    ``K, D`` at ``(x_n, v_n)``: the same to first order, and the same on linear forces.
    Exact implicit Euler on linear forces (same ``R(z) = 1/(1 - z)``, A-stable); on springs
    that rotate it deviates from implicit Euler by ``O(h^2)`` per step, so it is still first
    order, and its cost is fixed: one Jacobian, one linear solve, two force evaluations per
    step. The classical cloth method. Reference: D. Baraff, A. Witkin, "Large Steps in Cloth Simulation",
    SIGGRAPH 1998.
    """))

implicit_midpoint = register(ImplicitRK(
    [[Fr(1, 2)]], [1], name="implicit_midpoint", order=2, solver="newton", symplectic=True,
    doc="""Implicit midpoint rule (beyond the course), solved by Newton's method.

    ``y_{n+1} = y_n + h F((y_n + y_{n+1}) / 2)``: with ``v_m = (v_n + v_{n+1})/2``,
    ``x_{n+1} = x_n + h v_m``, ``v_{n+1} = v_n + h a(x_n + h/2 v_m, v_m)``.
    Tableau ``A = [[1/2]], b = [1]``.

    Order 2; symplectic and A-stable, ``R(z) = (1 + z/2)/(1 - z/2)``, ``|R(iy)| = 1``:
    neither gains nor loses energy on an oscillator. Cost as implicit Euler.
    """))

_g = 1.0 - 1.0 / sqrt(2.0)
sdirk2 = register(ImplicitRK(
    [[_g, 0.0], [1.0 - _g, _g]], [1.0 - _g, _g], name="sdirk2", order=2, solver="newton",
    doc="""Two-stage SDIRK of order 2 with ``gamma = 1 - 1/sqrt(2)`` (beyond the course).

    ``A = [[g, 0], [1 - g, g]], b = [1 - g, g]``: two implicit Euler-like stage solves
    per step, each with the Newton matrix ``I - h g M^-1 (h g K + D)``. Stiffly accurate
    (the new state is the second stage), so ``R(-inf) = 0``: L-stable, like implicit
    Euler, but second order. Reference: Alexander, SIAM J. Numer. Anal. 14 (1977);
    Hairer & Wanner, Solving ODEs II, IV.6.
    """))

_r = sqrt(3.0) / 6.0
gauss2 = register(ImplicitRK(
    [[0.25, 0.25 - _r], [0.25 + _r, 0.25]], [0.5, 0.5], name="gauss2", order=4, solver="newton",
    symplectic=True,
    doc="""Two-stage Gauss-Legendre collocation, order 4 (beyond the course).

    ``A = [[1/4, 1/4 - sqrt(3)/6], [1/4 + sqrt(3)/6, 1/4]], b = [1/2, 1/2]``. Both stages
    are solved together (a Newton system twice the size of implicit Euler's).
    Symplectic and A-stable with ``|R(iy)| = 1`` (``R`` is the (2,2) Pade approximant of
    ``e^z``): no numerical damping. Reference: Hairer, Lubich & Wanner, Geometric
    Numerical Integration, II.1.3.
    """))

radau_iia2 = register(ImplicitRK(
    [[Fr(5, 12), Fr(-1, 12)], [Fr(3, 4), Fr(1, 4)]], [Fr(3, 4), Fr(1, 4)], [Fr(1, 3), 1],
    name="radau_iia2", order=3, solver="newton",
    doc="""Two-stage Radau IIA, order 3 (beyond the course).

    ``A = [[5/12, -1/12], [3/4, 1/4]], b = [3/4, 1/4], c = [1/3, 1]``: stiffly accurate
    and L-stable, the two-stage member of the family behind scipy's ``Radau`` solver.
    Reference: Hairer & Wanner, Solving ODEs II, IV.5.
    """))
