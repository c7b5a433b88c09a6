"""Step limits of scenes: linearise at a state, take the eigenvalues, find the largest stable dt.

The scene's forces are linearised (the effects' Jacobians, uncounted), the eigenvalues
``lam`` of the first-order system found, and the largest ``dt`` with every ``dt * lam`` in
the method's stability region returned. A-stable methods have no limit; the fixed-point
solver of an implicit tableau converges only while ``dt rho(A) max|lam| < 1``.

A method without a scalar ``R(z)`` (leapfrog, Verlet, symplectic Euler, splittings) on a
*damped* scene is judged on its own one-step map of the whole linearised system (see
:func:`whole_system_limit`): a single eigenvalue does not say which oscillator it belongs to
(pure drag, eigenvalues 0 and ``-gamma/m``, is not the critically damped oscillator), and
non-proportional damping couples the modes.
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
from mslab.stability.limits import S_MIN, TOL, _ray_limit, oscillator_limit
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


#: free dofs up to which a damped scene is judged on a method's whole-system map (cost below)
WHOLE_SYSTEM_DOFS = 120


class _LinearSystem:
    """The linearised free dofs as a system for a method's own start/step: ``a = A x + B v``.

    The state's arrays have shape (n_free, columns): each column is one state, so one step
    maps a whole basis of perturbations at once. Counts nothing.
    """

    dissipative = False

    def __init__(self, A: np.ndarray, B: np.ndarray | None):
        self.A, self.B = A, B
        self.velocity_dependent = B is not None

    def rhs(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float]:
        a = self.A @ x
        return (a if self.B is None else a + self.B @ v), 0.0

    def acceleration(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self.rhs(x, v)[0]


def step_map(method: str | Integrator, A: np.ndarray, B: np.ndarray | None, dt: float) -> np.ndarray:
    """One-step map of a method on the linear system ``x'' = A x + B x'`` (whole system).

    The method's own ``start`` and ``step`` run on :class:`_LinearSystem` from the zero
    state with x, v and every memory entry shaped like x perturbed by the identity (all
    ``k n`` perturbations as the columns of one state); the map is exactly linear, so the
    result is the amplification matrix of the whole system, of size ``k n`` with
    ``k = 2 + number of array memory entries`` (the state of :func:`measured_amplification_matrix`).
    """
    m = get_method(method)
    n = A.shape[0]
    system = _LinearSystem(A, B)
    zero = m.start(system, State(np.zeros((n, 1)), np.zeros((n, 1)), (), 0.0), dt)
    slots = [i for i, item in enumerate(zero.memory) if isinstance(item, np.ndarray) and item.shape == (n, 1)]
    k = 2 + len(slots)
    eye = np.eye(k * n)
    blocks = [eye[j * n:(j + 1) * n] for j in range(k)]
    memory = list(zero.memory)
    for j, i in enumerate(slots):
        memory[i] = blocks[2 + j]
    new = m.step(system, State(blocks[0], blocks[1], tuple(memory), 0.0), dt)
    return np.vstack([new.x, new.v] + [new.memory[i] for i in slots])


@single_threaded_blas
def whole_system_limit(m: Integrator, A: np.ndarray, B: np.ndarray | None, guess: float) -> float:
    """Largest dt with the spectral radius of :func:`step_map` ``<= 1 + TOL`` (first crossing).

    From ``guess`` (the per-eigenvalue estimate, whose gap search finds an unstable gap of a
    decoupled mode however narrow: the map is probed first 1e-6 above it) steps of 2 % up or
    down bracket the first crossing, bisection narrows it to ``1e-10`` relative, and 16 steps
    geometrically spaced from ``S_MIN / max|lam|`` to the bracket must be stable too (else the full scan of
    :func:`mslab.stability.limits._ray_limit` decides). Cost: about 60-100 eigenvalue problems of
    size ``k n`` (``k = 2`` or 3), each ``O((k n)^3)``: milliseconds for the lessons' ropes,
    which is why only scenes up to :data:`WHOLE_SYSTEM_DOFS` free dofs are judged this way.
    """
    def stable(dt: float) -> bool:
        return bool(np.max(np.abs(np.linalg.eigvals(step_map(m, A, B, dt)))) <= 1.0 + TOL)

    top = float(np.max(np.abs(np.linalg.eigvals(np.block([[np.zeros_like(A), np.eye(A.shape[0])],
                                                          [A, np.zeros_like(A) if B is None else B]])))))
    lo = guess if 0 < guess < np.inf else 1.0 / top
    hi = lo * (1.0 + 1e-6)  # first just above the guess: the lower edge of a narrow gap it found
    if stable(lo):
        while stable(hi) and hi * top < 1e6:
            lo, hi = hi, hi * 1.02
        if hi * top >= 1e6:
            return np.inf
    else:
        while not stable(lo):
            if lo * top < S_MIN:
                return 0.0
            hi, lo = lo, lo / 1.02
    while hi - lo > 1e-10 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    below = np.geomspace(S_MIN / top, lo, 16)
    if all(stable(float(dt)) for dt in below):
        return float(lo)
    return _ray_limit(lambda s: np.array([0.0 if stable(si / top) else 2.0 for si in s])) / top


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
    stability region (Runge-Kutta methods, exact: ``R(dt J)`` has the eigenvalues
    ``R(dt lam)``). A method without a scalar ``R`` on a damped scene of at most
    :data:`WHOLE_SYSTEM_DOFS` free dofs: the largest dt at which its one-step map of the
    whole linearised system has spectral radius ``<= 1`` (:func:`whole_system_limit`, exact
    for the linearisation, coupled modes and pure drag included; about 100 dense eigenvalue
    problems of size 2-3 times the free dofs). Above that size each eigenvalue is read as its
    own oscillator (a real one as critically damped): exact only for modes that decouple with
    complex eigenvalues; for pure drag (eigenvalues 0 and ``-gamma/m``) it is too small. The
    same reading is kept for a user's method whose ``step`` needs more of the system than
    ``rhs`` and ``velocity_dependent``.
    A-stable implicit methods: inf. The fixed-point variant of implicit
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
        limit = _dt_limit(m, lam)
        if m.stability_function(np.zeros(1)) is None and np.any(np.abs(lam.real) > 0):
            K, D, inv_mass = linearise(scene, state.x, state.v, contacts=contacts)
            if D is not None and 0 < inv_mass.size <= WHOLE_SYSTEM_DOFS:
                minv = inv_mass[:, None]
                try:
                    limit = whole_system_limit(m, minv * K.toarray(), minv * D.toarray(), limit)
                except (AttributeError, TypeError):  # a user's step that needs more than rhs: per eigenvalue
                    pass
        per_system[key] = limit
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
