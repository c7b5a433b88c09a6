"""The answers of common student mistakes, for the exercises' one-line hints.

Each function returns ``{hint: answer}``: what a known wrong implementation returns on
the test's own input, so that :func:`mslab.grading.checks.check_known` can name the
mistake in one line when a wrong answer equals one of them (and only then). They use the
test's acceleration (``accel(x, v)``) and numpy only; the right answers come from the
library, in the tests.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Accel = Callable[..., np.ndarray]


def spring_forces(x: np.ndarray, springs: np.ndarray, stiffness: np.ndarray,
                  rest_length: np.ndarray) -> dict[str, tuple[np.ndarray]]:
    """Return Hooke forces with a flipped sign, an unnormalised direction, or no reaction on ``j``."""
    i, j = springs[:, 0], springs[:, 1]
    d = x[i] - x[j]
    length = np.linalg.norm(d, axis=1)

    def assemble(pair: np.ndarray, reaction: float = -1.0) -> tuple[np.ndarray]:
        f = np.zeros_like(x, dtype=float)
        np.add.at(f, i, pair)
        np.add.at(f, j, reaction * pair)
        return (f,)

    pull = (stiffness * (rest_length - length) / length)[:, None] * d
    return {"the sign: a stretched spring (l > L) pulls its two ends together": assemble(-pull),
            "the direction is not a unit vector: divide x_i - x_j by l": assemble(pull * length[:, None]),
            "the opposite force on j is missing: each spring pulls both its ends": assemble(pull, 0.0)}


def spring_jacobian(x: np.ndarray, springs: np.ndarray, stiffness: np.ndarray, rest_length: np.ndarray,
                    right: np.ndarray) -> dict[str, tuple[np.ndarray]]:
    """Return the Jacobian with a flipped sign, or its ``k u u^T`` part only (``right``: the right one)."""
    n, dim = x.shape
    K = np.zeros((n * dim, n * dim))
    for (i, j), k in zip(springs, stiffness, strict=True):
        u = (x[i] - x[j]) / np.linalg.norm(x[i] - x[j])
        block = -k * np.outer(u, u)
        si, sj = slice(i * dim, (i + 1) * dim), slice(j * dim, (j + 1) * dim)
        K[si, si] += block
        K[sj, sj] += block
        K[si, sj] -= block
        K[sj, si] -= block
    return {"the sign of K: a stretched spring's K pulls back, -k (u u^T + (1 - L/l)(I - u u^T))": (-right,),
            "only the -k u u^T part: the term -k (1 - L/l)(I - u u^T) of a stretched spring is missing": (K,)}


def old_state(x: np.ndarray, v: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Return the answer of a step that returns its input."""
    return {"the step returns the old state: x and v must both move": (x, v)}


def heun_midpoint(method: str, accel: Accel, x: np.ndarray, v: np.ndarray,
                  dt: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Return Heun's or the midpoint step with its slopes taken at the wrong times."""
    a = accel(x, v)
    if method == "heun":
        x_e, v_e = x + dt * v, v + dt * a
        return {"only the slope at the predicted end: Heun averages it with the slope at the start":
                (x + dt * v_e, v + dt * accel(x_e, v_e))}
    x_m, v_m = x + 0.5 * dt * v, v + 0.5 * dt * a
    x_e, v_e = x + dt * v, v + dt * a
    return {"the acceleration at the half step needs the half-step velocity too, a(x_1/2, v_1/2)":
            (x + dt * v_m, v + dt * accel(x_m, v)),
            "the slope at the end of the step (a whole Euler step ahead), not at its middle":
            (x + dt * v_e, v + dt * accel(x_e, v_e))}


def rk_stages(accel: Accel, x: np.ndarray, v: np.ndarray, dt: float, A: np.ndarray,
              b: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Return explicit Runge-Kutta steps with their stages built wrongly."""
    def step(x_slope_is_v0: bool, h_in_stages: float) -> tuple[np.ndarray, np.ndarray]:
        kx: list[np.ndarray] = []
        kv: list[np.ndarray] = []
        for i in range(len(b)):
            xi = x + h_in_stages * sum((A[i, j] * kx[j] for j in range(i)), np.zeros_like(x))
            vi = v + h_in_stages * sum((A[i, j] * kv[j] for j in range(i)), np.zeros_like(v))
            kx.append(v if x_slope_is_v0 else vi)
            kv.append(accel(xi, vi))
        return x + dt * sum(bi * k for bi, k in zip(b, kx, strict=True)), \
            v + dt * sum(bi * k for bi, k in zip(b, kv, strict=True))

    return {"the position slope of stage i is the stage's own velocity v_i, not v_n": step(True, dt),
            "the stages are y_n + h sum_j A_ij K_j: the sum is missing its factor times h": step(False, 1.0)}


def verlet_leapfrog(method: str, accel: Accel, x: np.ndarray, other: np.ndarray, dt: float,
                    steps: int = 1) -> dict[str, tuple[np.ndarray, ...]]:
    """Return ``steps`` Verlet steps with ``h a`` for ``h^2 a``, or leapfrog kicks at the old position.

    ``other`` is Verlet's ``x_prev`` or leapfrog's ``v_half``; the answer is Verlet's last
    position, or leapfrog's last ``(x, v_half)``.
    """
    for _ in range(steps):
        if method == "verlet":
            x, other = 2.0 * x - other + dt * accel(x), x
        else:
            x, other = x + dt * other, other + dt * accel(x)
    if method == "verlet":
        return {"the acceleration term is h^2 a(x_n), not h a": (x,)}
    return {"v jumps with the acceleration at the new position x_n+1, not at x_n": (x, other)}


def plane_contact(x: np.ndarray, v: np.ndarray, normal: np.ndarray, offset: float, stiffness: float,
                  friction: float, slip: float) -> dict[str, tuple[np.ndarray]]:
    """Return penalty forces pushing outside the wall too, or with friction along v or unregularised."""
    depth = offset - x @ normal
    fn = np.where(depth > 0.0, stiffness * depth, 0.0)
    vt = v - (v @ normal)[:, None] * normal[None, :]

    def force(fn: np.ndarray, along: np.ndarray, slip: float) -> tuple[np.ndarray]:
        speed = np.sqrt(np.sum(along * along, axis=1) + slip**2)
        with np.errstate(divide="ignore", invalid="ignore"):
            return (fn[:, None] * normal[None, :] - (friction * fn / speed)[:, None] * along,)

    return {"a force outside the wall: only particles with depth p > 0 are pushed":
            force(stiffness * depth, vt, slip),
            "friction along the whole velocity: it opposes the tangential part v - (n.v) n only":
            force(fn, v, slip),
            "friction not regularised: divide by sqrt(|v_t|^2 + eps^2), not by |v_t|": force(fn, vt, 0.0)}


def rk4_weights(b: np.ndarray) -> str | None:
    """Return the hint for RK4 weights in the wrong places, or all equal (None otherwise)."""
    right = np.array([1.0, 2.0, 2.0, 1.0]) / 6.0
    if b.shape != (4,) or np.allclose(b, right):
        return None
    if np.allclose(np.sort(b), np.sort(right)):
        return "the weights misordered: RK4's are 1/6, 1/3, 1/3, 1/6 (the two middle stages count twice)"
    if np.allclose(b, 0.25):
        return "equal weights: RK4's are 1/6, 1/3, 1/3, 1/6 (the two middle stages count twice)"
    return None
