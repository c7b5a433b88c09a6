"""The families: one class each, one stepping code path, a method is an instance holding coefficients.

``runge_kutta.py`` (:class:`ExplicitRK`, :class:`ImplicitRK`, Butcher tableaux), ``splitting.py``
(:class:`Splitting`, drift/kick coefficients), ``two_step.py`` (:class:`Verlet`, :class:`Leapfrog`,
the course's two-step and staggered forms of a splitting), ``local_global.py`` with
``local_step.py`` (the fast mass-spring method's local/global iteration); what they share:
``coefficients.py`` (coefficients as given, and as floats) and ``polynomials.py`` (the
stability polynomial of a tableau).
"""
