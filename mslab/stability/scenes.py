"""Step limits of scenes: linearise at a state, take the eigenvalues, find the largest stable dt.

The scene's forces are linearised (the effects' Jacobians, uncounted), the eigenvalues
``lam`` of the first-order system found, and the largest ``dt`` with every ``dt * lam`` in
the method's stability region returned. A-stable methods have no limit; the fixed-point
solver of an implicit tableau converges only while ``dt rho(A) max|lam| < 1``.
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from mslab.integrators.base import Integrator, get_method
from mslab.scene import Scene
from mslab.stability.functions import amplification
from mslab.stability.gaps import boundary
from mslab.stability.limits import S_MIN, _ray_limit, oscillator_limit
from mslab.state import State
from mslab.threads import single_threaded_blas

if TYPE_CHECKING:
    from collections.abc import Callable

    from mslab.system import System


def _free_dofs(system: System) -> np.ndarray:
    return np.flatnonzero(np.repeat(~system.pinned, system.dim))


def linearise(scene: Scene, x: np.ndarray | None = None, v: np.ndarray | None = None,
              contacts: str = "possible") -> tuple[sp.spmatrix, sp.spmatrix | None, np.ndarray]:
    """Stiffness and damping Jacobians at a state, restricted to the free degrees of freedom.

    Calls each effect's ``jacobians`` directly, so the run's counters (n_jac, n_force)
    are untouched.

    Parameters
    ----------
    scene : Scene
    x, v : ndarray, shape (n_particles, dim), optional
        Default ``scene.state0``.
    contacts : {"possible", "active"}
        ``"possible"`` (default): every free particle is treated as touching every
        collider (its penalty stiffness ``k n n^T`` added along the collider's normal at
        x), since contacts that start later limit the step just the same; ``"active"``:
        only the contacts present at x.

    Returns
    -------
    K : sparse (n_free, n_free)
        ``df/dx``.
    D : sparse (n_free, n_free) or None
        ``df/dv``, None when no effect depends on velocity.
    inv_mass : ndarray, shape (n_free,)
    """
    system = scene.system
    x = scene.state0.x if x is None else x
    v = scene.state0.v if v is None else v
    size = system.n_particles * system.dim
    K = sp.csr_matrix((size, size))
    D = None
    for e in system.effects:
        kx, kv = e.jacobians(x, v)
        if e.may_touch and contacts == "possible":
            kx = e.contact_jacobian(x)
        if kx is not None:
            K = K + kx
        if kv is not None:
            D = kv if D is None else D + kv
    free = _free_dofs(system)
    inv_mass = np.repeat(system.inv_mass, system.dim)[free]
    K = K.tocsr()[free][:, free]
    if D is not None:
        D = D.tocsr()[free][:, free]
        if D.count_nonzero() == 0:
            D = None
    return K, D, inv_mass


@single_threaded_blas
def eigenvalues(scene: Scene, contacts: str = "possible", n_modes: int = 24,
                dense_limit: int = 600, state: State | None = None) -> np.ndarray:
    """Eigenvalues ``lam`` of the linearised first-order system at ``scene.state0``.

    Without velocity-dependent forces: ``lam = +- i w`` from the largest eigenvalue
    ``w^2`` of ``-M^-1/2 K M^-1/2`` (symmetrised; dense for small systems, Lanczos
    ``eigsh`` otherwise). With damping: eigenvalues of ``J = [[0, I], [M^-1 K, M^-1 D]]``
    (dense up to ``dense_limit`` free dofs, else by ARPACK ``eigs``). Only the ``n_modes``
    eigenvalues of largest modulus with ``Re lam <= 0`` (physically stable modes; growing
    modes are the physics, not the method) and ``Im lam >= 0`` (one of each conjugate
    pair) are returned: the stiff end of the spectrum limits explicit steps.

    ``state`` (default ``scene.state0``) is where the system is linearised.

    Returns
    -------
    ndarray of complex, shape (n,)
    """
    state = scene.state0 if state is None else state
    K, D, inv_mass = linearise(scene, state.x, state.v, contacts=contacts)
    n = inv_mass.size
    if n == 0:
        return np.zeros(0, dtype=complex)
    if D is None:
        s = sp.diags(np.sqrt(inv_mass))
        S = -(s @ (0.5 * (K + K.T)) @ s)
        if n <= dense_limit:
            w2 = sla.eigvalsh(S.toarray())
        else:
            w2 = spla.eigsh(S.tocsc(), k=min(n_modes, n - 1), which="LA", return_eigenvectors=False,
                            tol=1e-8)
        w2 = w2[w2 > 0]
        return 1j * np.sqrt(w2)
    minv = sp.diags(inv_mass)
    J = sp.bmat([[None, sp.identity(n)], [minv @ K, minv @ D]], format="csr")
    if 2 * n <= 2 * dense_limit:
        lam = np.linalg.eigvals(J.toarray())
    else:
        lam = spla.eigs(J.tocsc(), k=min(n_modes, 2 * n - 2), which="LM", return_eigenvectors=False, tol=1e-8)
    scale = max(float(np.max(np.abs(lam))), 1e-300)
    lam = lam[(lam.real <= 1e-9 * scale) & (lam.imag >= -1e-12 * scale)]
    return lam[np.argsort(-np.abs(lam))[:n_modes]]


def _dt_limit(m: Integrator, lam: np.ndarray) -> float:
    """Largest dt with ``dt * lam_k`` stable for every mode (scan in ``s = dt max|lam|``)."""
    lam = lam[np.abs(lam) > 0]
    if lam.size == 0:
        return np.inf
    top = float(np.max(np.abs(lam)))
    if np.all(np.abs(lam.real) <= 1e-12 * top):  # undamped: the oscillator test
        return oscillator_limit(m) / top
    unit = lam / top

    def rho(s: np.ndarray):
        z = s[:, None] * unit[None, :]
        return np.max(np.abs(amplification(m, z)), axis=1)

    limit = _ray_limit(rho, functions=boundary(m, np.unique(unit)))
    if limit == 0.0:  # unstable at S_MIN, yet damping may leave a small stable step
        limit = _small_limit(rho)
    return limit / top


def _small_limit(rho: Callable[[np.ndarray], np.ndarray], smallest: float = 1e-12) -> float:
    """Largest ``s < S_MIN`` with ``rho <= 1`` on the ray (0 when none down to ``smallest``).

    A method whose stability region touches the imaginary axis only at 0 (forward Euler,
    Heun) is stable on a damped mode ``lam = -zeta w + i w sqrt(1 - zeta^2)`` for small
    steps only: forward Euler for ``dt <= 2 zeta / w``, which on a lightly damped stiff scene
    is far below the scan's ``S_MIN``. Stable here means ``rho <= 1`` with no tolerance:
    near ``s = 0`` the margin ``1 - rho`` is of order ``zeta s``, not round-off.
    """
    grid = np.geomspace(S_MIN, smallest, 241)  # descending
    stable = np.flatnonzero(rho(grid) <= 1.0)
    if stable.size == 0:
        return 0.0
    lo, hi = grid[stable[0]], grid[stable[0] - 1]
    while hi - lo > 1e-13 * hi:
        mid = 0.5 * (lo + hi)
        if rho(np.array([mid]))[0] <= 1.0:
            lo = mid
        else:
            hi = mid
    return float(lo)


#: per System: eigenvalues and limits by (contacts, state bytes[, method]); scenes are not mutated
_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _cached_eigenvalues(scene: Scene, contacts: str, state: State | None = None) -> np.ndarray:
    state = scene.state0 if state is None else state
    per_system = _CACHE.setdefault(scene.system, {})
    key = (contacts, state.x.tobytes(), state.v.tobytes())
    if key not in per_system:
        if len(per_system) > 64:
            per_system.clear()
        per_system[key] = eigenvalues(scene, contacts=contacts, state=state)
    return per_system[key]


def max_stable_dt(scene: Scene, method: str | Integrator, contacts: str = "possible",
                  state: State | None = None) -> float:
    """Largest stable dt of a method on a scene, linearised at ``scene.state0``.

    Undamped scenes: ``oscillator_limit(method) / w_max``. Damped scenes: the largest
    dt with every ``dt * lam`` (eigenvalues of the first-order Jacobian) in the method's
    stability region. A-stable implicit methods: inf. The fixed-point variant of implicit
    Euler converges only while ``dt * max|lam| < 1`` (its iteration map is ``dt J``), so
    for it the contraction limit :func:`contraction_dt` is returned.

    Parameters
    ----------
    scene : Scene
    method : str or Integrator
    contacts : {"possible", "active"}
        See :func:`linearise`: colliders limit the step wherever particles may touch them.
    state : State, optional
        Linearise here instead of at ``scene.state0`` (e.g. a stretched, loaded state
        taken from a trajectory).

    Returns
    -------
    float
        Seconds; inf when no limit applies. The Jacobians are evaluated without touching
        the system's counters.
    """
    m = get_method(method)
    if m.a_stable:
        return np.inf
    if getattr(m, "solver", None) == "fixed_point":
        return contraction_dt(scene, contacts, state) / max(float(np.max(np.abs(np.linalg.eigvals(m.A)))),
                                                            1e-300)
    lam = _cached_eigenvalues(scene, contacts, state)
    per_system = _CACHE[scene.system]
    state = scene.state0 if state is None else state
    key = (contacts, state.x.tobytes(), state.v.tobytes(), m)
    if key not in per_system:
        per_system[key] = _dt_limit(m, lam)
    return per_system[key]


def contraction_dt(scene: Scene, contacts: str = "possible", state: State | None = None) -> float:
    """Step below which the fixed-point iteration of implicit Euler contracts: ``1 / max|lam|``."""
    lam = _cached_eigenvalues(scene, contacts, state)
    top = float(np.max(np.abs(lam))) if lam.size else 0.0
    return np.inf if top == 0 else 1.0 / top


def predicted_stable_dt(scene: Scene, method: str | Integrator, max_dofs: int = 5000) -> float | None:
    """``max_stable_dt`` for the simulate pre-check; None when skipped (too many dofs).

    Never raises: a failing eigenvalue computation also gives None.
    """
    system = scene.system
    if system.n_particles * system.dim > max_dofs:
        return None
    try:
        return float(max_stable_dt(scene, method))
    except (ValueError, np.linalg.LinAlgError, spla.ArpackError, spla.ArpackNoConvergence):
        return None
