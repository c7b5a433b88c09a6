"""The catalogue: modules that register the built-in methods (``mslab.methods()``).

``explicit_tableaux.py``, ``implicit_tableaux.py`` (Butcher tableaux), ``symplectic.py``
(the drift/kick splittings: symplectic Euler, velocity Verlet, Forest-Ruth, Yoshida 6),
``verlet_leapfrog.py`` (the two-step adapters), ``fast_mass_spring.py``. Every module here is
imported by :func:`mslab.integrators.discover`.
"""
