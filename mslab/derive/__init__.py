"""Sympy derivations: Taylor series, local errors, orders and stability functions of methods.

Every method is read from its coefficients (the very ones that step): Runge-Kutta tableaux
``A, b`` (explicit or implicit) and drift/kick splittings. Orders come from the rooted-tree
order conditions, exact for exact coefficients (``Fraction``, sympy numbers, strings such
as ``"19372/6561"``) and up to round-off for floats; local errors from Taylor series on the
scalar model problems ``y' = f(y)`` and ``x'' = a(x)`` (lecture notes, eqs. 4-5). Methods without
coefficients are run symbolically through their own ``step``.

Modules: :mod:`~mslab.derive.series` (Taylor series), :mod:`~mslab.derive.trees` and
:mod:`~mslab.derive.conditions` (order conditions), :mod:`~mslab.derive.coefficients`
(exact and float arithmetic), :mod:`~mslab.derive.reading` (what a method carries),
:mod:`~mslab.derive.runs` (one step as a series), :mod:`~mslab.derive.analysis` (the API).
"""

from mslab.derive.analysis import Derivation, analyse, local_error, order, stability_function
from mslab.derive.series import A, F, derivatives, h, taylor, v, x, z

__all__ = ["A", "Derivation", "F", "analyse", "derivatives", "h", "local_error", "order",
           "stability_function", "taylor", "v", "x", "z"]
