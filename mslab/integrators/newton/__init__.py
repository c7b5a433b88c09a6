"""Solving the implicit methods' stage equations: Newton and fixed-point iteration, linear algebra.

``solvers.py`` (Newton, fixed point, the line search), ``linear.py`` (Newton's linear systems:
kept factorisations, the policies ``fresh``/``reuse``/``auto``), ``newton_matrix.py`` (the
matrix ``M - c^2 K - c D`` on a kept pattern), ``pcg.py`` (preconditioned conjugate gradients).
"""
