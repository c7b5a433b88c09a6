"""Key of exercise 05 (Verlet and leapfrog): wrong start-ups, and steps with a wrong term."""

def _verlet_start(t):
    prob, v0 = t.start_state()
    h, x0 = t.DT, prob.x0
    a0 = prob(x0)
    # the hints name the mistake, never the right formula (the README gives the Taylor expansion)
    return {"mistakes": {"the h^2/2 a term is missing: expand x(t_0 - h) to second order": [x0 - h * v0],
                         "a forward step, not a backward one: x_-1 lies one step before x_0":
                         [x0 + h * v0 + h * h / 2 * a0],
                         "the sign of the h^2/2 a term: (-h)^2 is positive": [x0 - h * v0 - h * h / 2 * a0]}}


def _leapfrog_start(t):
    prob, v0 = t.start_state()
    h = t.DT
    hint = "a whole Euler step, not half of one (v_1/2 = v_0 + h/2 a_0)"
    return {"mistakes": {hint: [v0 + h * prob(prob.x0)]}}


def _steps(method):
    def key(t):
        prob, x, other, h = t.library_start(method)
        for _ in range(5):
            if method == "verlet":  # h a for h^2 a
                x, other = 2.0 * x - other + h * prob(x), x
            else:  # the kick at the old position
                x, other = x + h * other, other + h * prob(x)
        if method == "verlet":
            return {"mistakes": {"the acceleration term is h^2 a(x_n), not h a": [x]}}
        hint = "v jumps with the acceleration at the new position x_n+1, not at x_n"
        return {"mistakes": {hint: [x, other]}}
    return key


CASES = {"verlet_start": _verlet_start, "verlet_steps": _steps("verlet"),
         "leapfrog_start": _leapfrog_start, "leapfrog_steps": _steps("leapfrog")}
