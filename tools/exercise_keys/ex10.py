"""Key of exercise 10 (the cheapest method): the fitted error models, and the step for a target."""

import numpy as np


def _fit(dts, errors):
    """The least-squares fit of log e = log C + p log h: (p, log C)."""
    p, log_c = np.polyfit(np.log(np.asarray(dts, dtype=float)), np.log(np.asarray(errors, dtype=float)), 1)
    return float(p), float(log_c)


def _exact_c(t):
    _, log_c = _fit(*t.exact_power_law())
    return {"expected": [np.exp(log_c)], "mistakes": {"log C, not C: the fit's intercept is log C": [log_c]}}


def _noisy(t):
    p, log_c = _fit(*t.noisy_power_law())
    return {"expected": [p, np.exp(log_c)]}


def _step(t):
    C, p, target = t.one_method()
    return {"expected": [(target / C) ** (1.0 / p)], "mistakes": {
        "the power p, not the root: solve C h^p = target for h": [(target / C) ** p],
        "C and the target swapped: a smaller target must give a smaller step": [(C / target) ** (1.0 / p)]}}


CASES = {"exact_power_law_C": _exact_c, "noisy_power_law": _noisy, "step_for_target": _step}
