"""The splitting methods: both symplectic Euler variants, velocity Verlet, Forest-Ruth, Yoshida 6."""

from fractions import Fraction as Fr

from mslab.integrators.base import register
from mslab.integrators.families.splitting import Splitting

half = Fr(1, 2)

symplectic_euler = register(Splitting(
    [0, 1], [1], name="symplectic_euler", order=1,
    doc="""Symplectic Euler, velocity first (semi-implicit Euler), eqs. 9-10 of the lecture notes.

    ``v_{n+1} = v_n + h a(x_n, v_n)``,  ``x_{n+1} = x_n + h v_{n+1}``.
    Splitting ``drift = [0, 1], kick = [1]``.

    Order 1; one force evaluation per step; symplectic. On ``x'' = -w^2 x`` stable for
    ``h w < 2`` (strictly: at ``h w = 2`` the map is a Jordan block and grows linearly),
    with bounded energy error. Other names: Euler-Cromer, semi-implicit Euler.
    """))

symplectic_euler_x = register(Splitting(
    [1, 0], [1], name="symplectic_euler_x", order=1,
    doc="""Symplectic Euler, position first, eqs. 7-8 of the lecture notes.

    ``x_{n+1} = x_n + h v_n``,  ``v_{n+1} = v_n + h a(x_{n+1}, v_n)``.
    Splitting ``drift = [1, 0], kick = [1]``.

    Order 1; one force evaluation per step; symplectic (the adjoint of
    ``symplectic_euler``); same stability limit ``h w < 2``.
    """))

velocity_verlet = register(Splitting(
    [0, 1, 0], [half, half], name="velocity_verlet", order=2,
    doc="""Velocity Verlet (beyond the course's list): kick, drift, kick.

    ``v_{n+1/2} = v_n + h/2 a_n``,  ``x_{n+1} = x_n + h v_{n+1/2}``,
    ``v_{n+1} = v_{n+1/2} + h/2 a_{n+1}``. Splitting ``drift = [0, 1, 0], kick = [1/2, 1/2]``.

    Order 2; one force evaluation per step (the last kick's acceleration is the next first
    one; one start-up evaluation); symplectic and time-reversible; stable for ``h w < 2``.
    Same positions as Verlet and leapfrog. With velocity-dependent forces each kick is a
    midpoint-rule step in v (two evaluations; see :mod:`mslab.integrators.families.splitting`).
    """))

_theta = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
forest_ruth = register(Splitting(
    [_theta / 2, (1 - _theta) / 2, (1 - _theta) / 2, _theta / 2], [_theta, 1 - 2 * _theta, _theta],
    name="forest_ruth", order=4,
    doc="""Forest-Ruth, order 4 (beyond the course): three Störmer-Verlet steps of sizes
    ``theta h, (1 - 2 theta) h, theta h`` with ``theta = 1/(2 - 2^(1/3))``.

    ``drift = [theta/2, (1-theta)/2, (1-theta)/2, theta/2]``,
    ``kick = [theta, 1 - 2 theta, theta]``. The middle step runs backwards in time
    (``1 - 2 theta < 0``): the price of raising a symmetric method's order by two.

    Order 4; three force evaluations per step; symplectic; oscillator limit about
    ``h w < 1.573``. Reference: Forest & Ruth, Physica D 43 (1990) 105;
    Yoshida, Phys. Lett. A 150 (1990) 262.
    """))

_w1, _w2, _w3 = -1.17767998417887100695, 0.235573213359358133684, 0.784513610477557263819
_w0 = 1.0 - 2.0 * (_w1 + _w2 + _w3)
_weights = [_w3, _w2, _w1, _w0, _w1, _w2, _w3]
yoshida6 = register(Splitting(
    [_weights[0] / 2] + [(a + b) / 2 for a, b in zip(_weights, _weights[1:], strict=False)]
    + [_weights[-1] / 2], _weights, name="yoshida6", order=6,
    doc="""Yoshida's sixth-order composition ("solution A"), beyond the course.

    Seven Störmer-Verlet steps of sizes ``w3, w2, w1, w0, w1, w2, w3`` times ``h`` with
    ``w1 = -1.1776799841788710``, ``w2 = 0.2355732133593581``,
    ``w3 = 0.7845136104775573``, ``w0 = 1 - 2 (w1 + w2 + w3)``; neighbouring half
    drifts merged. Order 6; seven force evaluations per step; symplectic.
    Reference: H. Yoshida, Phys. Lett. A 150 (1990) 262, table 1.
    """))
