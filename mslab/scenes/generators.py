"""Scene generators: the harmonic oscillator (with its closed-form solution) and the chain."""

from __future__ import annotations

import numpy as np

from mslab.scenes.builder import Scene, SceneBuilder


def oscillator_solution(t, u0: float, w0: float, beta: float, v0: float = 0.0):
    """Closed form of ``u'' + 2 beta u' + w0^2 u = 0``: ``(u(t), u'(t))``.

    Under-, critically and over-damped cases through one complex formula
    ``u = e^{-beta t} (u0 cos(wd t) + (v0 + beta u0) sin(wd t)/wd)``, ``wd = sqrt(w0^2 - beta^2)``.
    """
    t = np.asarray(t, dtype=float)
    wd = np.sqrt(complex(w0 * w0 - beta * beta))
    decay = np.exp(-beta * t)
    B = v0 + beta * u0
    if abs(wd) < 1e-12 * max(w0, 1.0):
        sin_over = t.astype(complex)       # sin(wd t)/wd -> t
        cos_wd = np.ones_like(t, dtype=complex)
        dsin_over = np.ones_like(t, dtype=complex)   # d/dt [sin(wd t)/wd] = cos(wd t)
        dcos = np.zeros_like(t, dtype=complex)
    else:
        sin_over = np.sin(wd * t) / wd
        cos_wd = np.cos(wd * t)
        dsin_over = cos_wd
        dcos = -wd * np.sin(wd * t)
    u = decay * (u0 * cos_wd + B * sin_over)
    du = -beta * u + decay * (u0 * dcos + B * dsin_over)
    return u.real, du.real


def oscillator(stiffness: float = 1.0, mass: float = 1.0, gamma: float = 0.0,
               displacement: float = 0.5, velocity: float = 0.0, rest_length: float = 1.0,
               dim: int = 1, t_end: float = 2.0 * np.pi, dt: float = 0.01) -> Scene:
    """One mass on a spring to a pinned anchor, optionally with viscous drag.

    ``m u'' = -k u - gamma u'`` for the stretch ``u``: the course's model problem, with a
    closed-form solution attached as ``scene.exact``. Keep ``|displacement|`` below
    ``rest_length`` (and the amplitude with it): a 1D spring squeezed through zero length
    flips direction and the dynamics is no longer linear.
    """
    b = SceneBuilder(dim)
    e = np.zeros(dim)
    e[0] = 1.0
    anchor = b.add_particle(np.zeros(dim), mass=mass, pinned=True)
    p = b.add_particle((rest_length + displacement) * e, mass=mass, velocity=velocity * e)
    b.add_spring(anchor, p, stiffness, rest_length=rest_length)
    if gamma > 0:
        b.add_damping(gamma)
    b.set_run(method="rk4", dt=dt, t_end=t_end)
    w0 = float(np.sqrt(stiffness / mass))
    beta = gamma / (2.0 * mass)

    def exact(t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        u, du = oscillator_solution(t, displacement, w0, beta, velocity)
        x = np.zeros((t.size, 2, dim))
        v = np.zeros((t.size, 2, dim))
        x[:, 1, 0] = rest_length + u
        v[:, 1, 0] = du
        return x, v

    kind = "damped " if gamma > 0 else ""
    return b.build("oscillator", f"{kind}harmonic oscillator, w0 = {w0:g}", exact=exact)


def chain(n: int = 10, dim: int = 2, length: float = 1.0, mass: float = 1.0, stiffness: float = 100.0,
          damping: float = 0.0, gamma: float = 0.0, gravity: float | None = 9.81,
          pin: str = "first") -> Scene:
    """A chain of ``n`` particles on the x axis joined by structural springs.

    Parameters
    ----------
    n : int
        Number of particles (n - 1 springs).
    length, mass : float
        Total length and total mass (equal masses).
    stiffness, damping : float
        Spring stiffness k and damping c along each spring.
    gamma : float
        Viscous drag on every particle (0: none, the effect is not built).
    gravity : float or None
        Strength of gravity along -y (-x in 1D); None or 0: no gravity effect.
    pin : {"first", "both", "none"}
    """
    b = SceneBuilder(dim)
    xs = np.linspace(0.0, length, n)
    m = mass / n
    for i, xi in enumerate(xs):
        pos = np.zeros(dim)
        pos[0] = xi
        pinned = (pin in ("first", "both") and i == 0) or (pin == "both" and i == n - 1)
        b.add_particle(pos, mass=m, pinned=pinned)
    for i in range(n - 1):
        b.add_spring(i, i + 1, stiffness, damping=damping)
    if gravity:
        g = np.zeros(dim)
        g[min(1, dim - 1)] = -gravity
        b.add_gravity(g)
    if gamma:
        b.add_damping(gamma)
    b.set_run(method="rk4", dt=1e-3, t_end=2.0)
    return b.build("chain", f"chain of {n} particles, k = {stiffness:g}")


def _offsets(ndim: int, kind: str) -> list[tuple[int, ...]]:
    """Neighbour offsets of a regular grid, one of each +/- pair (first non-zero > 0)."""
    import itertools

    out = []
    for o in itertools.product((-2, -1, 0, 1, 2), repeat=ndim):
        nz = [c for c in o if c != 0]
        if not nz or nz[0] < 0:
            continue
        if kind == "structural" and len(nz) == 1 and abs(nz[0]) == 1:
            out.append(o)
        elif kind == "shear" and len(nz) >= 2 and all(abs(c) == 1 for c in nz):
            out.append(o)
        elif kind == "bend" and len(nz) == 1 and abs(nz[0]) == 2:
            out.append(o)
    return out


def grid_springs(shape: tuple[int, ...], kind: str) -> np.ndarray:
    """Index pairs (n_springs, 2) of one spring kind on a regular grid of ``shape``.

    ``structural``: axis neighbours (resist stretching); ``shear``: diagonals (resist
    shearing; in 3D face and body diagonals); ``bend``: every second particle along an
    axis (resist bending). Particles are numbered in C order of ``shape``.
    """
    index = np.arange(int(np.prod(shape))).reshape(shape)
    pairs = []
    for o in _offsets(len(shape), kind):
        src = tuple(slice(max(0, -c), n - max(0, c)) for c, n in zip(o, shape, strict=True))
        dst = tuple(slice(max(0, c), n - max(0, -c)) for c, n in zip(o, shape, strict=True))
        pairs.append(np.stack([index[src].ravel(), index[dst].ravel()], axis=1))
    return np.concatenate(pairs) if pairs else np.empty((0, 2), dtype=np.int64)


def cloth(nx: int = 10, ny: int = 10, size: float = 1.0, mass: float = 1.0,
          structural: float = 500.0, shear: float | None = 50.0, bend: float | None = 5.0,
          damping: float = 0.0, gamma: float = 0.0, gravity: float | None = 9.81,
          pin: str = "top_corners") -> Scene:
    """A square cloth of ``nx * ny`` particles in the x-z plane (3D), hanging from its top.

    Row ``j = ny - 1`` is the top edge (z = 0); the cloth hangs down to ``z = -size``.
    Spring kinds have their own stiffness; ``None`` (or 0) leaves a kind out.
    ``pin``: ``top_corners``, ``top_edge`` or ``none``.
    """
    b = SceneBuilder(3)
    gx, gz = np.meshgrid(np.linspace(0.0, size, nx), np.linspace(-size, 0.0, ny), indexing="xy")
    pos = np.stack([gx.ravel(), np.zeros(nx * ny), gz.ravel()], axis=1)  # index = j * nx + i
    b.add_particles(pos, mass=mass / (nx * ny))
    top = [(ny - 1) * nx + i for i in range(nx)]
    pins = {"top_corners": [top[0], top[-1]], "top_edge": top, "none": []}[pin]
    for p in pins:
        b.pin(p)
    for kind, k in (("structural", structural), ("shear", shear), ("bend", bend)):
        if k:
            b.add_springs(grid_springs((ny, nx), kind), k, damping=damping, kind=kind)
    if gravity:
        b.add_gravity([0.0, 0.0, -gravity])
    if gamma:
        b.add_damping(gamma)
    b.set_run(method="implicit_euler", dt=1e-2, t_end=2.0)
    return b.build("cloth", f"{nx}x{ny} cloth")


def lattice(n: tuple[int, int, int] = (4, 4, 4), size: float = 1.0, mass: float = 1.0,
            structural: float = 500.0, shear: float | None = 200.0, bend: float | None = None,
            damping: float = 0.0, gamma: float = 0.0, origin=(0.0, 0.0, 0.0)) -> Scene:
    """A 3D block of particles (a soft body) with structural, shear and bend springs."""
    b = SceneBuilder(3)
    axes = [np.linspace(0.0, size, k) for k in n]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3) + np.asarray(origin, float)
    b.add_particles(grid, mass=mass / grid.shape[0])
    for kind, k in (("structural", structural), ("shear", shear), ("bend", bend)):
        if k:
            b.add_springs(grid_springs(tuple(n), kind), k, damping=damping, kind=kind)
    if gamma:
        b.add_damping(gamma)
    b.set_run(method="implicit_euler", dt=5e-3, t_end=2.0)
    return b.build("lattice", f"{n[0]}x{n[1]}x{n[2]} lattice")
