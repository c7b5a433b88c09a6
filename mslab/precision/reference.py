"""Reference solutions: the scene's closed form, or scipy's DOP853 at rtol = atol = 1e-12.

The scipy reference integrates the first-order system ``y = (x, v)``,
``y' = (v, a(x, v))`` built from the very same ``scene.system.acceleration`` (pinned
particles have zero acceleration and stay put); it is cached per scene object and t_end.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from mslab.errors import InstabilityError
from mslab.scenes.builder import Scene

if TYPE_CHECKING:
    import numpy.typing as npt

    from mslab.system import System


@dataclass
class Reference:
    """The accurate solution errors are measured against.

    Attributes
    ----------
    t_end : float
    x_end, v_end : ndarray, shape (n_particles, dim)
        The reference state at ``t_end``.
    kind : str
        ``"exact"`` (closed form) or ``"DOP853"`` (scipy, rtol = atol = ``rtol``).
    n_force : int
        Force evaluations the scipy reference cost (0 for a closed form).
    """

    t_end: float
    x_end: np.ndarray
    v_end: np.ndarray
    kind: str
    n_force: int = 0
    _dense: object = field(default=None, repr=False)

    def at(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Return the reference ``(x, v)`` at times ``t``, each of shape (n_t, n_particles, dim)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self._dense(t)


_REFERENCES: dict = {}


def _flat_rhs(system: System, shape: tuple[int, ...],
              backend: str = "numpy") -> Callable[[float, np.ndarray], np.ndarray]:
    """``f(t, y)`` of the first-order system ``y = (x, v)`` for solve_ivp.

    ``backend="numpy"``: ``System.acceleration`` (counts n_force); ``"numba"``: the same
    accelerations from mslab's compiled forces (:class:`mslab.fast.ForceModel`, equal to
    round-off; scipy counts its own ``nfev``).
    """
    n = int(np.prod(shape))
    if backend == "numba":
        from mslab.fast import ForceModel

        model = ForceModel(system)

        def compiled(t: float, y: np.ndarray):
            a, _ = model.rhs(y[:n].reshape(shape), y[n:].reshape(shape))
            return np.concatenate([y[n:], a.ravel()])

        return compiled

    def f(t: float, y: np.ndarray):
        a = system.acceleration(y[:n].reshape(shape), y[n:].reshape(shape))
        return np.concatenate([y[n:], a.ravel()])

    return f


def _flat_jacobian(system: System, shape: tuple[int, ...]) -> Callable:
    """``df/dy = [[0, I], [M^-1 K, M^-1 D]]`` (sparse) for scipy's implicit solvers; counts n_jac."""
    import scipy.sparse as sp

    n = int(np.prod(shape))
    minv = system.inv_mass_diag

    def jac(t: float, y: np.ndarray):
        K, D = system.jacobians(y[:n].reshape(shape), y[n:].reshape(shape))
        lower_v = minv @ D if D is not None else sp.csr_matrix((n, n))
        return sp.bmat([[None, sp.identity(n)], [minv @ K, lower_v]], format="csc")

    return jac


def _y0(scene: Scene) -> np.ndarray:
    return np.concatenate([scene.state0.x.ravel(), scene.state0.v.ravel()])


def reference_solution(scene: Scene, t_end: float, *, use_exact: bool = True,
                       rtol: float = 1e-12, atol: float = 1e-12) -> Reference:
    """Return the reference solution of ``scene`` on ``[0, t_end]`` (cached per scene and t_end).

    Parameters
    ----------
    scene : Scene
    t_end : float
    use_exact : bool
        Use ``scene.exact`` when the scene has it; False forces the scipy reference
        (to check it against the closed form).
    rtol, atol : float
        Tolerances of ``solve_ivp(method="DOP853")``.

    Returns
    -------
    Reference
    """
    t_end = float(t_end)
    shape = scene.state0.x.shape
    if use_exact and scene.exact is not None:
        x_end, v_end = scene.exact(np.array([t_end]))
        return Reference(t_end, x_end[0], v_end[0], "exact", 0, scene.exact)
    key = (id(scene), scene.name, t_end, rtol, atol)
    hit = _REFERENCES.get(key)
    if hit is not None and hit[0]() is scene:
        return hit[1]
    from scipy.integrate import solve_ivp

    before = scene.system.counters.n_force
    sol = solve_ivp(_flat_rhs(scene.system, shape), (0.0, t_end), _y0(scene), method="DOP853",
                    rtol=rtol, atol=atol, dense_output=True)
    if not sol.success:
        raise InstabilityError(f"reference solution (DOP853) failed: {sol.message}")
    n = int(np.prod(shape))

    def dense(t: np.ndarray):
        y = sol.sol(t).T  # (n_t, 2n)
        return y[:, :n].reshape((-1,) + shape), y[:, n:].reshape((-1,) + shape)

    ref = Reference(t_end, sol.y[:n, -1].reshape(shape), sol.y[n:, -1].reshape(shape), "DOP853",
                    scene.system.counters.n_force - before, dense)
    _REFERENCES[key] = (weakref.ref(scene), ref)
    return ref
