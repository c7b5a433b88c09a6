"""The fast mass-spring method of Liu, Bargteil, O'Brien and Kavan (2013), beyond the course."""

from mslab.integrators.base import register
from mslab.integrators.families.local_global import LocalGlobal

fast_mass_spring = register(LocalGlobal(
    name="fast_mass_spring", iterations=10,
    doc="""Fast mass-spring method (Liu et al. 2013): implicit Euler by 10 local/global iterations.

    Minimises implicit Euler's objective ``g(x) = |x - y|_M^2 / (2 h^2) + E(x)``,
    ``y = x_n + h v_n`` (eq. 27 of the lecture notes as an optimisation), by block coordinate descent:
    local step ``d_q = L_q (x_i - x_j)/|x_i - x_j|`` per spring (compiled), global step
    ``(M + h gamma + h^2 L) x = M y + h gamma x_n + h^2 (J d + f_other)`` with a constant
    matrix factored once per scene and dt; then ``v_{n+1} = (x_{n+1} - x_n)/h``.

    Order 1. Per step: 10 iterations, each one force evaluation (the local step) and one
    solve with the kept factors; one factorisation per scene and dt, done by ``start`` before
    the first frame. Chebyshev acceleration (Wang 2015) is the option
    ``LocalGlobal(iterations=10, chebyshev=True)``: the same fixed point, reached in fewer
    iterations at the same cost each (:mod:`mslab.integrators.families.local_global`). With many iterations
    it converges to implicit Euler's step; 10 iterations stop early (more numerical damping
    than implicit Euler). Linear limit (the course's oscillator): the local step is exact and
    the step is implicit Euler's, ``R(z) = 1/(1 - z)``: A-stable. Other names: projective
    dynamics for springs. Reference: T. Liu, A. W. Bargteil, J. F. O'Brien, L. Kavan,
    ACM Trans. Graph. 32(6), 209 (2013).
    """))
