"""Linear stability: Dahlquist's test equation, the oscillator test and step limits of scenes.

* :mod:`~mslab.stability.functions` — ``R(z)`` and the oscillator maps, from each method's
  own coefficients, and the same maps measured by running the method's ``step``;
* :mod:`~mslab.stability.limits` — real interval, imaginary limit, oscillator limit;
* :mod:`~mslab.stability.scenes` — linearised scenes, eigenvalues, ``max_stable_dt``.
"""

from mslab.stability.functions import (
    amplification,
    amplification_matrix,
    amplification_sympy,
    measured_amplification_matrix,
    region_grid,
    same_spectrum,
    spectral_radius,
    tableau,
)
from mslab.stability.limits import TOL, imag_limit, oscillator_limit, real_interval, rk_polynomials, summary
from mslab.stability.scenes import (
    contraction_dt,
    eigenvalues,
    linearise,
    max_stable_dt,
    predicted_stable_dt,
)

__all__ = ["TOL", "amplification", "amplification_matrix", "amplification_sympy", "contraction_dt",
           "eigenvalues", "imag_limit", "linearise", "max_stable_dt", "measured_amplification_matrix",
           "oscillator_limit", "predicted_stable_dt", "real_interval", "region_grid", "rk_polynomials",
           "same_spectrum", "spectral_radius", "summary", "tableau"]
