"""Common mistakes of the lessons' "complete a cell" tasks, kept out of the notebooks.

A lesson's cell shows how its answer is checked (a reference computed from the library or from
coordinates), but not the wrong answers it recognises: printed next to the student's ``TODO``,
a wrong formula that differs from the right one by the term its hint names gives the answer
away. Each function here returns the ``mistakes`` mapping of :mod:`mslab.exercise_cells`
(a one-line hint -> the wrong answer) and builds every wrong answer from the cell's own
reference, so this module does not hold the formula either::

    check_function("dt_limit", dt_limit, reference=..., cases=...,
                   mistakes=common_mistakes.dt_limit(reference))
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["modified_energy", "evals_for", "dt_limit", "bend_length", "newton_dv"]


def modified_energy(kept: Callable) -> dict[str, Callable]:
    """Lesson 06: ``kept(x, v, h, w)`` is the quadratic form symplectic Euler keeps (v^2 / 2 scaled)."""
    def energy(x: float, v: float, h: float, w: float) -> float:
        return 0.5 * v * v + 0.5 * w * w * x * x

    return {
        "that is the plain energy E, which the step does not keep: add the x v term": energy,
        "the x v term has the wrong sign (that form is kept by the position-first variant)":
            lambda x, v, h, w: kept(x, -v, h, w),
        "the x v term is twice too large: recheck the factor 1/2 of the squares":
            lambda x, v, h, w: 2.0 * kept(x, v, h, w) - energy(x, v, h, w),
    }


def evals_for(line: Callable) -> dict[str, Callable]:
    """Lesson 07: ``line(target, e0, n0, p)`` walks the log-log line of slope -p to the error target."""
    return {
        "the exponent is 1/p: the error falls like n^-p, so n grows like error^(-1/p)":
            lambda target, e0, n0, p: line(target, e0, n0, 1.0 / p),
        "the ratio is upside down: a smaller target needs more evaluations, not fewer":
            lambda target, e0, n0, p: line(e0 * e0 / target, e0, n0, p),
        "that ignores the order: the error falls like n^-p, not like 1/n":
            lambda target, e0, n0, p: line(target, e0, n0, 1.0),
    }


def dt_limit(limit: Callable) -> dict[str, Callable]:
    """Lesson 08: ``limit(mass, stiffness)`` is the library's stable step on a penalty contact."""
    return {
        "the factor 2 is missing: solve |2 - dt^2 w^2| < 2 for dt":
            lambda mass, stiffness: 0.5 * limit(mass, stiffness),
        "mass and stiffness are swapped: a stiffer collider (a larger w = sqrt(k/m)) needs a smaller step":
            lambda mass, stiffness: limit(stiffness, mass),
        "that is how long a contact lasts (half a period), not the step limit":
            lambda mass, stiffness: 0.5 * np.pi * limit(mass, stiffness),
        "the square root is missing: like the oscillator of lessons 03 and 05, the step is limited through "
        "the product dt w, and w = sqrt(k/m)":
            lambda mass, stiffness: 0.5 * limit(mass, stiffness) ** 2,
    }


def bend_length(distance: Callable) -> dict[str, Callable]:
    """Lesson 09: ``distance(h, phi)`` is the folded particles' distance (from coordinates, phi < pi/2)."""
    return {
        "the spring does shorten: after the fold its two halves are no longer in line":
            lambda h, phi: distance(h, 0.0),
        "phi is the kink; the angle between the two halves is pi - phi (law of cosines)":
            lambda h, phi: distance(h, np.pi - phi),
        "each half is tilted by phi/2, not phi, against the spring's direction":
            lambda h, phi: distance(h, 2.0 * phi),
    }


def _step_dv(method: str, mass: float, stiffness: float, drag: float, h: float, u: float, v: float) -> float:
    """Velocity change of one library step on the damped oscillator scene."""
    from mslab import get_method
    from mslab.scenes.oscillator import oscillator

    osc = oscillator(stiffness=stiffness, mass=mass, gamma=drag, displacement=u, velocity=v)
    return float(get_method(method).step(osc.system, osc.state0, h).v[1, 0] - v)


def newton_dv(mass: float, stiffness: float, drag: float, h: float, u: float, v: float) -> dict[str, float]:
    """Lesson 11: wrong velocity changes of one linearised implicit Euler step, from library steps."""
    right = _step_dv("baraff_witkin", mass, stiffness, drag, h, u, v)
    # h times the force at x_n + h v_n (a forward Euler step from there, times the mass)
    ahead = mass * _step_dv("euler", mass, stiffness, drag, h, u + h * v, v)
    return {
        "the h^2 K v_n term is missing: x_(n+1) - x_n = h v_n + h dv, not h dv":
            _step_dv("baraff_witkin", mass, stiffness, drag, h, u - h * v, v),
        "check the signs: with K = -k and D = -c the matrix M - hD - h^2 K is m + h c + h^2 k":
            ahead / (2.0 * mass - ahead / right),
        "that is forward Euler's h f / m: the step must solve for the new velocity":
            _step_dv("euler", mass, stiffness, drag, h, u, v),
    }
