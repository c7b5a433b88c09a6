"""Key of exercise 03 (Heun and the midpoint method): steps with their slopes taken at the wrong times."""


def _wrong_slopes(method, accel, x, v, dt):
    a = accel(x, v)
    x_e, v_e = x + dt * v, v + dt * a
    if method == "heun":
        return {"only the slope at the predicted end: Heun averages it with the slope at the start":
                [x + dt * v_e, v + dt * accel(x_e, v_e)]}
    x_m, v_m = x + 0.5 * dt * v, v + 0.5 * dt * a
    return {"the acceleration at the half step needs the half-step velocity too, a(x_1/2, v_1/2)":
            [x + dt * v_m, v + dt * accel(x_m, v)],
            "the slope at the end of the step (a whole Euler step ahead), not at its middle":
            [x + dt * v_e, v + dt * accel(x_e, v_e)]}


def _swinging(t):
    prob, x0, v0, h = t.swinging_spring()
    return {"mistakes": _wrong_slopes("heun", prob, x0, v0, h)}


def _chain(method):
    def key(t):
        prob, v0 = t.moving_chain()
        return {"mistakes": _wrong_slopes(method, prob, prob.x0, v0, t.DT)}
    return key


CASES = {"swinging_spring": _swinging, "heun_moving_chain": _chain("heun"),
         "midpoint_moving_chain": _chain("midpoint")}
