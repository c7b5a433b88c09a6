"""Key of exercise 04 (RK4 from its tableau): explicit Runge-Kutta steps with their stages built wrongly."""

import numpy as np


def rk_stages(accel, x, v, dt, A, b):
    """The steps of two stage mistakes (also exercise 12's): ``{hint: [x_new, v_new]}``."""
    def step(x_slope_is_v0, h_in_stages):
        kx, kv = [], []
        for i in range(len(b)):
            xi = x + h_in_stages * sum((A[i, j] * kx[j] for j in range(i)), np.zeros_like(x))
            vi = v + h_in_stages * sum((A[i, j] * kv[j] for j in range(i)), np.zeros_like(v))
            kx.append(v if x_slope_is_v0 else vi)
            kv.append(accel(xi, vi))
        return [x + dt * sum(bi * k for bi, k in zip(b, kx, strict=True)),
                v + dt * sum(bi * k for bi, k in zip(b, kv, strict=True))]

    return {"the position slope of stage i is the stage's own velocity v_i, not v_n": step(True, dt),
            "the stages are y_n + h sum_j A_ij K_j: the sum is missing its factor times h": step(False, 1.0)}


def _chain(name):
    def key(t):
        (prob, v0, dt), method = t.damped_chain() if name == "rk4" else t.short_chain(), t.get_method(name)
        return {"mistakes": rk_stages(prob, prob.x0, v0, dt, method.A, method.b)}
    return key


CASES = {"rk4_chain": _chain("rk4"), "euler_chain": _chain("euler"), "heun_chain": _chain("heun")}
