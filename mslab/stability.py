"""Linear stability: Dahlquist's test equation, the oscillator test and step limits of scenes.

Two test problems (seed section 2.6):

* **Dahlquist**, ``y' = lam y`` (seed eq. 29) with ``z = lam * dt``. A Runge-Kutta
  method with tableau ``(A, b)`` maps ``y_n`` to ``y_{n+1} = R(z) y_n`` with
  ``R(z) = 1 + z b^T (I - z A)^-1 1``; forward Euler gives ``R = 1 + z`` (seed eq. 32).
  ``R`` is computed from the very coefficients that step (``ExplicitRK.A, .b``);
  implicit Euler is the one-stage tableau ``A = [[1]], b = [1]``, implicit midpoint
  ``A = [[1/2]], b = [1]``.
* **Oscillator**, ``x'' = -w^2 x - gamma x'``. The partitioned methods (symplectic Euler,
  Verlet, leapfrog, velocity Verlet) treat x and v differently, so they have no scalar
  ``R(z)``: one step is a linear map of the method's whole state, its *amplification
  matrix* (:func:`amplification_matrix`). In the scaled variables ``(x, dt v, ...)`` it
  depends only on ``h_omega = dt w`` and ``h_gamma = dt gamma``.

For a partitioned method, ``amplification(method, z)`` is defined through the real
oscillator whose first-order eigenvalues are ``z`` and ``conj(z)`` (``h_omega^2 = |z|^2``,
``h_gamma = -2 Re z``; a real ``z`` gives the critically damped oscillator with the double
eigenvalue ``z``): it returns the eigenvalue of largest modulus of that oscillator's
amplification matrix. For a Runge-Kutta method this definition gives ``|R(z)|`` again
(the matrix is ``R(dt J)`` with eigenvalues ``R(z)`` and ``R(conj z)``), so stability
regions of all methods are comparable; on the imaginary axis it is the undamped oscillator.

Limits are found numerically from these functions (scan along a ray, then bisection), with
the criterion ``|R| <= 1 + 1e-10`` and a resolution ``|dt lam| >= 0.01``: a method that is
already unstable at ``|dt lam| = 0.01`` gets the limit 0 (forward Euler on an undamped
oscillator), one that is stable up to ``1e6`` gets ``inf``.
"""

from __future__ import annotations

import itertools
import weakref
from functools import lru_cache

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from mslab.integrators.base import Integrator, get_method
from mslab.integrators.explicit import ExplicitRK
from mslab.integrators.implicit import ImplicitEuler, ImplicitEulerFixedPoint, ImplicitMidpoint
from mslab.integrators.symplectic import Leapfrog, SymplecticEuler, SymplecticEulerX, VelocityVerlet, Verlet
from mslab.scenes.builder import Scene, SceneBuilder
from mslab.state import State
from mslab.threads import single_threaded_blas

#: ``|R| <= 1 + TOL`` counts as stable (unit-modulus eigenvalues carry roundoff).
TOL = 1e-10
#: Smallest ``|dt lam|`` examined; a method unstable there gets the limit 0.
S_MIN = 1e-2
#: Largest ``|dt lam|`` examined; a method stable up to here gets the limit inf.
S_MAX = 1e6
_GRID = np.geomspace(S_MIN, S_MAX, 1201)

__all__ = ["TOL", "amplification", "amplification_matrix", "amplification_sympy", "contraction_dt",
           "describe_step_limit", "eigenvalues", "imag_limit", "linearise", "max_stable_dt",
           "measured_amplification_matrix", "oscillator_limit", "predicted_stable_dt", "real_interval",
           "region_grid", "same_spectrum", "spectral_radius", "summary", "tableau"]


# -- tableaux and R(z) ----------------------------------------------------------------------------

def tableau(method: str | Integrator) -> tuple[np.ndarray, np.ndarray] | None:
    """Butcher tableau ``(A, b)`` of a Runge-Kutta method, None for partitioned methods.

    Explicit methods return their own stepping coefficients; implicit Euler (Newton and
    fixed point) is ``([[1]], [1])``, implicit midpoint ``([[1/2]], [1])``.
    """
    m = get_method(method)
    if isinstance(m, ExplicitRK):
        return m.A, m.b
    if isinstance(m, ImplicitEuler | ImplicitEulerFixedPoint):
        return np.array([[1.0]]), np.array([1.0])
    if isinstance(m, ImplicitMidpoint):
        return np.array([[0.5]]), np.array([1.0])
    return None


def _rk_R(A: np.ndarray, b: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``R(z) = 1 + z b^T (I - z A)^-1 1`` for an array of z (any shape)."""
    s = b.size
    if not np.any(np.triu(A)):  # explicit: (I - zA)^-1 = sum_k (zA)^k, a polynomial of degree s
        coef = [1.0]
        w = np.ones(s)
        for _ in range(s):
            coef.append(float(b @ w))
            w = A @ w
        return np.polynomial.polynomial.polyval(z, coef)
    # implicit: R(z) = det(I - zA + z 1 b^T) / det(I - zA), which is inf (not an error) at a pole
    flat = z.ravel().astype(complex)
    mats = np.eye(s)[None] - flat[:, None, None] * A[None]
    num = np.linalg.det(mats + flat[:, None, None] * np.outer(np.ones(s), b)[None])
    den = np.linalg.det(mats)
    with np.errstate(divide="ignore", invalid="ignore"):
        R = np.where(den == 0, np.inf, num / np.where(den == 0, 1.0, den))
    return R.reshape(z.shape)


def amplification(method: str | Integrator, z) -> np.ndarray:
    """Amplification factor ``R(z)``, ``z = dt * lam``, for an array of complex z.

    Parameters
    ----------
    method : str or Integrator
    z : complex array_like, any shape

    Returns
    -------
    ndarray of complex, shape of z
        For Runge-Kutta methods ``R(z)`` from the tableau; for partitioned methods the
        eigenvalue of largest modulus of the amplification matrix of the oscillator with
        eigenvalues ``z, conj(z)`` (see the module docstring).
    """
    z = np.asarray(z, dtype=complex)
    tab = tableau(method)
    if tab is not None:
        return _rk_R(tab[0], tab[1], z)
    mats = amplification_matrix(method, np.abs(z), -2.0 * z.real)
    mu = np.linalg.eigvals(mats.reshape((-1,) + mats.shape[-2:]))
    pick = np.take_along_axis(mu, np.argmax(np.abs(mu), axis=-1)[:, None], axis=-1)[:, 0]
    return pick.reshape(z.shape)


def amplification_sympy(method: str | Integrator):
    """Exact ``R(z)`` of a Runge-Kutta method as a sympy rational function of ``z``.

    The float coefficients of the tableau are turned into the nearest simple fractions
    (``nsimplify``), e.g. ``1/6``. Raises TypeError for partitioned methods (use
    :func:`amplification_matrix`).
    """
    import sympy

    tab = tableau(method)
    if tab is None:
        raise TypeError(f"{get_method(method).name} is a partitioned method without a scalar R(z); "
                        "use amplification_matrix(method, h_omega, h_gamma)")
    z = sympy.Symbol("z")

    def exact(value):
        return sympy.nsimplify(float(value), rational=True, tolerance=1e-13)

    A = sympy.Matrix(tab[0].shape[0], tab[0].shape[1], [exact(a) for a in tab[0].ravel()])
    b = sympy.Matrix([exact(v) for v in tab[1]])
    s = b.shape[0]
    inner = (sympy.eye(s) - z * A).LUsolve(sympy.ones(s, 1))
    return sympy.factor(sympy.cancel(1 + z * (b.T * inner)[0, 0]))


# -- the oscillator: amplification matrices ------------------------------------------------------

def _partitioned_step(m: Integrator, w2, g, y: list):
    """One step of a partitioned method on ``x'' = -w2 x - g x'`` in scaled variables (dt = 1).

    ``y`` is the list of state components; returns the new list. These are the update
    equations of the integrator classes, written out for the linear oscillator.
    """
    def acc(x, u):
        return -w2 * x - g * u

    if isinstance(m, SymplecticEuler):            # (x, u): u' = u + a(x, u), x' = x + u'
        x, u = y
        u1 = u + acc(x, u)
        return [x + u1, u1]
    if isinstance(m, SymplecticEulerX):           # (x, u): x' = x + u, u' = u + a(x', u)
        x, u = y
        x1 = x + u
        return [x1, u + acc(x1, u)]
    if isinstance(m, Verlet):                     # (x, u, x_prev)
        x, u, xp = y
        a = acc(x, u)
        x1 = 2.0 * x - xp + a
        return [x1, x1 - x + 0.5 * a, x]
    if isinstance(m, Leapfrog):                   # (x, u_half, a_prev)
        x, uh, ap = y
        x1 = x + uh
        a = acc(x1, uh + 0.5 * ap)
        return [x1, uh + a, a]
    if isinstance(m, VelocityVerlet):             # (x, u, a_prev)
        x, u, ap = y
        x1 = x + u + 0.5 * ap
        a = acc(x1, u + ap)
        return [x1, u + 0.5 * (ap + a), a]
    raise TypeError(f"no amplification matrix for {m!r}")


def _state_size(m: Integrator) -> int:
    return 2 if tableau(m) is not None or isinstance(m, SymplecticEuler | SymplecticEulerX) else 3


def amplification_matrix(method: str | Integrator, h_omega, h_gamma=0.0) -> np.ndarray:
    """One-step map of a method on the damped oscillator ``x'' = -w^2 x - gamma x'``.

    Parameters
    ----------
    method : str or Integrator
    h_omega : array_like
        ``dt * w``.
    h_gamma : array_like, broadcast with ``h_omega``
        ``dt * gamma`` (gamma per unit mass).

    Returns
    -------
    ndarray, shape broadcast(h_omega, h_gamma) + (k, k)
        The map of the scaled state: ``k = 2``, ``(x, dt v)`` for one-step methods;
        ``k = 3`` for the methods with memory: Verlet ``(x, dt v, x_prev)``, leapfrog
        ``(x, dt v_half, dt^2 a_prev)``, velocity Verlet ``(x, dt v, dt^2 a_prev)``.
        For a Runge-Kutta tableau it is ``R(dt J)`` with ``dt J = [[0, 1], [-w2, -g]]``.
    """
    m = get_method(method)
    w2, g = np.broadcast_arrays(np.square(np.asarray(h_omega, dtype=float)),
                                np.asarray(h_gamma, dtype=float))
    shape = w2.shape
    w2, g = w2.ravel(), g.ravel()
    n = w2.size
    tab = tableau(m)
    if tab is not None:
        A, b = tab
        s = b.size
        Z = np.zeros((n, 2, 2))
        Z[:, 0, 1] = 1.0
        Z[:, 1, 0] = -w2
        Z[:, 1, 1] = -g
        # stages K = (I - A kron Z)^-1 (1 kron Z) y,  y' = (I + (b^T kron Z) K) y
        big = np.eye(2 * s)[None] - np.einsum("ij,nab->niajb", A, Z).reshape(n, 2 * s, 2 * s)
        rhs = np.einsum("i,nab->niab", np.ones(s), Z).reshape(n, 2 * s, 2)
        K = np.linalg.solve(big, rhs).reshape(n, s, 2, 2)
        M = np.eye(2)[None] + np.einsum("i,niab->nab", b, K)
        return M.reshape(shape + (2, 2))
    k = _state_size(m)
    M = np.empty((n, k, k))
    for j in range(k):
        y = [np.full(n, 1.0 if i == j else 0.0) for i in range(k)]
        M[:, :, j] = np.stack(_partitioned_step(m, w2, g, y), axis=-1)
    return M.reshape(shape + (k, k))


def spectral_radius(matrices: np.ndarray) -> np.ndarray:
    """Largest eigenvalue modulus of each matrix in a stack (..., k, k)."""
    return np.max(np.abs(np.linalg.eigvals(matrices)), axis=-1)


def measured_amplification_matrix(method: str | Integrator, h_omega: float, h_gamma: float = 0.0,
                                  delta: float = 1e-2) -> np.ndarray:
    """The one-step map *measured* by running the real integrator on an oscillator scene.

    Independent of :func:`amplification_matrix`: a SceneBuilder scene (pinned anchor at
    ``x = -1``, one free unit mass at ``x = 0``, a 1D spring of rest length 1 and stiffness
    ``h_omega^2``, Damping ``h_gamma`` when > 0) is stepped with ``dt = 1`` by the method's
    own ``start``/``step`` from the equilibrium with one state component perturbed by
    ``delta`` at a time. The state components are x, v and every memory entry shaped like
    x (Verlet's ``x_prev``, leapfrog's ``v_half`` and ``a``, velocity Verlet's ``a``); the
    dissipated-power entries do not feed back and are left out. The spring stays longer
    than 0, so the map is exactly linear.

    Returns
    -------
    ndarray, shape (k, k)
        ``k = 2 + number of array memory entries``. Its non-zero eigenvalues equal those of
        :func:`amplification_matrix` (leapfrog reports v as an extra output: one more zero).
    """
    m = get_method(method)
    b = SceneBuilder(1)
    anchor = b.add_particle([-1.0], mass=1.0, pinned=True)
    p = b.add_particle([0.0], mass=1.0)
    b.add_spring(anchor, p, stiffness=float(h_omega) ** 2, rest_length=1.0)
    if h_gamma > 0:
        b.add_damping(float(h_gamma))
    scene = b.build("measured oscillator")
    system = scene.system
    eq = m.start(system, scene.state0, 1.0)
    slots = [i for i, item in enumerate(eq.memory)
             if isinstance(item, np.ndarray) and item.shape == eq.x.shape]

    def flat(state: State) -> np.ndarray:
        return np.array([state.x[p, 0], state.v[p, 0]] + [state.memory[i][p, 0] for i in slots])

    def perturbed(j: int) -> State:
        x, v = eq.x.copy(), eq.v.copy()
        memory = list(eq.memory)
        if j == 0:
            x[p, 0] += delta
        elif j == 1:
            v[p, 0] += delta
        else:
            item = memory[slots[j - 2]].copy()
            item[p, 0] += delta
            memory[slots[j - 2]] = item
        return State(x, v, tuple(memory), 0.0)

    base = flat(m.step(system, eq, 1.0))
    k = 2 + len(slots)
    return np.stack([(flat(m.step(system, perturbed(j), 1.0)) - base) / delta for j in range(k)], axis=1)


def same_spectrum(m1: np.ndarray, m2: np.ndarray, atol: float = 1e-9) -> float:
    """Largest distance between the eigenvalues of two maps, ignoring eigenvalues below ``atol``.

    Returns inf when the numbers of non-negligible eigenvalues differ.
    """
    e1 = [e for e in np.linalg.eigvals(m1) if abs(e) > atol]
    e2 = [e for e in np.linalg.eigvals(m2) if abs(e) > atol]
    if len(e1) != len(e2):
        return np.inf
    if not e1:
        return 0.0
    return min(max(abs(a - b) for a, b in zip(e1, perm, strict=True)) for perm in itertools.permutations(e2))


# -- limits along rays --------------------------------------------------------------------------

def _ray_limit(rho, chunk: int = 100) -> float:
    """Largest s with ``rho(s') <= 1 + TOL`` for all s' in [S_MIN, s] (0 / inf at the ends).

    ``rho`` maps an array of s to spectral radii; the grid is scanned in chunks from small
    s upwards, then the first failure is located by bisection.
    """
    first = None
    for start in range(0, _GRID.size, chunk):
        bad = np.flatnonzero(~(rho(_GRID[start:start + chunk]) <= 1.0 + TOL))
        if bad.size:
            first = start + int(bad[0])
            break
    if first is None:
        return np.inf
    if first == 0:
        return 0.0
    lo, hi = _GRID[first - 1], _GRID[first]
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if rho(np.array([mid]))[0] <= 1.0 + TOL:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    return float(lo)


@lru_cache(maxsize=256)
def _real_interval(m: Integrator) -> float:
    s = _ray_limit(lambda s: np.abs(amplification(m, -s)))
    return -s


@lru_cache(maxsize=256)
def _imag_limit(m: Integrator) -> float:
    return _ray_limit(lambda s: np.maximum(np.abs(amplification(m, 1j * s)),
                                           np.abs(amplification(m, -1j * s))))


@lru_cache(maxsize=256)
def _oscillator_limit(m: Integrator) -> float:
    return _ray_limit(lambda s: spectral_radius(amplification_matrix(m, s)))


def real_interval(method: str | Integrator) -> float:
    """Left end ``a`` of the real stability interval ``[a, 0]`` (``-inf``: whole negative axis)."""
    return _real_interval(get_method(method))


def imag_limit(method: str | Integrator) -> float:
    """Largest ``y`` with ``|R(i t)| <= 1`` for all ``|t| <= y`` (0: none, inf: whole axis)."""
    return _imag_limit(get_method(method))


def oscillator_limit(method: str | Integrator) -> float:
    """Largest ``dt * w`` for which the method is stable on ``x'' = -w^2 x``.

    From the spectral radius of :func:`amplification_matrix` (``<= 1 + TOL``). 0 for
    forward Euler (never stable undamped), 2 for symplectic Euler and Verlet, ``2 sqrt 2``
    for RK4, inf for the A-stable implicit methods.
    """
    return _oscillator_limit(get_method(method))


def region_grid(method: str | Integrator, re: np.ndarray, im: np.ndarray) -> np.ndarray:
    """``|R(re + i im)|`` on the grid ``meshgrid(re, im)``, shape (len(im), len(re))."""
    zr, zi = np.meshgrid(np.asarray(re, dtype=float), np.asarray(im, dtype=float))
    return np.abs(amplification(method, zr + 1j * zi))


def summary(methods=None) -> list[dict]:
    """Real interval, imaginary limit and oscillator limit for each method (a table's rows)."""
    from mslab.integrators.base import methods as all_methods

    names = all_methods() if methods is None else [get_method(m).name for m in methods]
    rows = []
    for name in names:
        m = get_method(name)
        rows.append({"method": name, "explicit": bool(m.explicit), "order": int(m.order),
                     "real_interval": real_interval(m), "imag_limit": imag_limit(m),
                     "oscillator_limit": oscillator_limit(m)})
    return rows


# -- scenes: linearisation and step limits -------------------------------------------------------

def _free_dofs(system) -> np.ndarray:
    return np.flatnonzero(np.repeat(~system.pinned, system.dim))


def linearise(scene: Scene, x: np.ndarray | None = None, v: np.ndarray | None = None,
              contacts: str = "possible"):
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
    from mslab.effects.base import block_diagonal
    from mslab.effects.colliders import PenaltyCollider

    system = scene.system
    x = scene.state0.x if x is None else x
    v = scene.state0.v if v is None else v
    size = system.n_particles * system.dim
    K = sp.csr_matrix((size, size))
    D = None
    for e in system.effects:
        kx, kv = e.jacobians(x, v)
        if isinstance(e, PenaltyCollider) and contacts == "possible":
            _, normal, _ = e._contact(x)
            touching = np.linalg.norm(normal, axis=1, keepdims=True) > 0
            normal = np.where(touching, normal, 1.0 / np.sqrt(x.shape[1]))
            blocks = -e.stiffness * normal[:, :, None] * normal[:, None, :]
            kx = block_diagonal(blocks, np.arange(system.n_particles), system.n_particles)
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

    def rho(s):
        z = s[:, None] * unit[None, :]
        return np.max(np.abs(amplification(m, z)), axis=1)

    return _ray_limit(rho) / top


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
    if isinstance(m, ImplicitEulerFixedPoint):
        return contraction_dt(scene, contacts, state)
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


def describe_step_limit(scene: Scene, method: str | Integrator, dt: float) -> str:
    """One line for the run command: the predicted stable dt and the margin of ``dt``.

    E.g. ``"predicted stable dt = 0.02828 (rk4); dt = 0.01 is 0.354 x the limit"``.
    """
    m = get_method(method)
    limit = max_stable_dt(scene, m)
    if np.isinf(limit):
        return f"predicted stable dt: no limit ({m.name} is A-stable)"
    if limit == 0:
        return f"predicted stable dt: none ({m.name} is unstable at every dt on this scene)"
    verdict = "within" if dt <= limit else "ABOVE"
    return (f"predicted stable dt = {limit:.4g} ({m.name}); "
            f"dt = {dt:g} is {dt / limit:.3g} x the limit ({verdict})")
