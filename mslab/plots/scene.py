"""Configuration plots and animations of a scene. Plotting only: positions come from a Trajectory."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection

from mslab.effects.base import Ball, Halfspace

if TYPE_CHECKING:
    import numpy.typing as npt
    from matplotlib.axes import Axes

    from mslab.effects.base import Effect
    from mslab.scenes.builder import Scene
    from mslab.trajectory import Trajectory


def _as_2d(x: np.ndarray) -> np.ndarray:
    """1D positions drawn on the x axis: (n, 1) -> (n, 2)."""
    return np.column_stack([x[:, 0], np.zeros(len(x))]) if x.shape[1] == 1 else x


def _new_axes(dim: int):
    fig = plt.figure(figsize=(6, 5))
    return fig.add_subplot(projection="3d") if dim == 3 else fig.add_subplot()


def _limits(points: np.ndarray, margin: float = 0.08) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = points.min(axis=0), points.max(axis=0)
    span = max(float(np.max(hi - lo)), 1e-9)
    return lo - margin * span, hi + margin * span


def _draw_colliders(ax: Axes, colliders: Sequence[Effect], dim: int, lo: np.ndarray, hi: np.ndarray) -> None:
    """Draw the outline of every effect that has one (:meth:`Effect.outline`); skip the others."""
    for shape in (c.outline() for c in colliders):
        if isinstance(shape, Ball):
            c, r = shape.center, shape.radius
            if dim == 3:
                u, w = np.meshgrid(np.linspace(0, 2 * np.pi, 24), np.linspace(0, np.pi, 12))
                ax.plot_wireframe(
                    c[0] + r * np.cos(u) * np.sin(w),
                    c[1] + r * np.sin(u) * np.sin(w),
                    c[2] + r * np.cos(w),
                    color="0.6",
                    lw=0.5,
                )
            else:
                ax.add_patch(plt.Circle(c[:2], r, color="0.85", zorder=0))
        elif isinstance(shape, Halfspace):
            n, d = shape.normal, shape.offset
            if dim == 3 and abs(n[2]) > 1e-12:
                gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 2), np.linspace(lo[1], hi[1], 2))
                ax.plot_surface(gx, gy, (d - n[0] * gx - n[1] * gy) / n[2], color="0.8", alpha=0.4)
            elif dim == 2:
                t = np.array([-n[1], n[0]])
                p0 = d * n
                s = 2.0 * float(np.max(hi - lo)) + float(np.linalg.norm(p0))
                ax.plot(*np.stack([p0 - s * t, p0 + s * t]).T, color="0.5", lw=2, zorder=0)


def plot_configuration(x: npt.ArrayLike, springs: npt.ArrayLike, ax: Axes | None = None,
                       pinned: npt.ArrayLike | None = None, colliders: Sequence[Effect] = (),
                       limits: tuple[np.ndarray, np.ndarray] | None = None, color: Any = "C0") -> Axes:
    """Plot the particles and springs of one configuration, in 2D or 3D.

    Parameters
    ----------
    x : ndarray, shape (n_particles, dim)
        Positions (dim 1, 2 or 3; 1D is drawn along the x axis).
    springs : ndarray, shape (n_springs, 2)
        Particle index pairs joined by springs.
    ax : matplotlib Axes, optional
        A 3D Axes for dim = 3; one is created when omitted.
    pinned : ndarray of bool, shape (n_particles,), optional
        Pinned particles are drawn as black squares.
    colliders : sequence of effects, optional
        Those with an outline (:meth:`~mslab.effects.base.Effect.outline`: planes, spheres)
        are drawn as grey shapes; the others are skipped.
    limits : (lo, hi) arrays, optional
        Axis limits; default from ``x``.

    Returns
    -------
    ax
    """
    return _draw(x, springs, ax, pinned, colliders, limits, color)[0]


def _draw(x: npt.ArrayLike, springs: npt.ArrayLike, ax: Axes | None, pinned: npt.ArrayLike | None,
          colliders: Sequence[Effect], limits: tuple[np.ndarray, np.ndarray] | None,
          color: Any) -> tuple[Axes, Callable[[np.ndarray], None]]:
    """Do ``plot_configuration`` and also return an ``update(x)`` callback for animations."""
    x = np.asarray(x, dtype=float)
    dim = x.shape[1]
    springs = np.asarray(springs, dtype=np.int64).reshape(-1, 2)
    ax = ax if ax is not None else _new_axes(dim)
    pts = x if dim == 3 else _as_2d(x)
    lo, hi = limits if limits is not None else _limits(pts)
    _draw_colliders(ax, colliders, dim, lo, hi)
    free = np.ones(len(x), bool) if pinned is None else ~np.asarray(pinned, bool)
    if dim == 3:
        from mpl_toolkits.mplot3d.art3d import Line3DCollection

        lines = Line3DCollection(pts[springs], colors=color, linewidths=0.8)
        ax.add_collection3d(lines)
        (dots,) = ax.plot(*pts[free].T, "o", ms=2.5, color=color)
        if not free.all():
            ax.plot(*pts[~free].T, "s", ms=5, color="k")
        ax.set(
            xlim=(lo[0], hi[0]),
            ylim=(lo[1], hi[1]),
            zlim=(lo[2], hi[2]),
            xlabel="x [m]",
            ylabel="y [m]",
            zlabel="z [m]",
        )
        ax.set_box_aspect(np.maximum(hi - lo, 0.2 * float(np.max(hi - lo))))

        def update(y: np.ndarray):
            lines.set_segments(y[springs])
            dots.set_data_3d(*y[free].T)
    else:
        lines = LineCollection(pts[springs], colors=color, linewidths=1.0)
        ax.add_collection(lines)
        (dots,) = ax.plot(*pts[free].T, "o", ms=3, color=color)
        if not free.all():
            ax.plot(*pts[~free].T, "s", ms=6, color="k")
        ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), xlabel="x [m]", ylabel="y [m]" if dim == 2 else "")
        ax.set_aspect("equal")

        def update(y: np.ndarray):
            y = _as_2d(y)
            lines.set_segments(y[springs])
            dots.set_data(*y[free].T)

    return ax, update


def animate(traj: Trajectory, scene: Scene, path: str | Path, fps: int = 15, max_frames: int = 60,
            progress: Any = None) -> Path:
    """Write an animation of a trajectory: GIF (Pillow) or MP4 (ffmpeg), chosen by ``path``'s suffix.

    Parameters
    ----------
    traj : Trajectory
        Saved samples; at most ``max_frames`` evenly spaced ones are drawn.
    scene : Scene
        For the springs, pinned particles and colliders.
    path : str or Path
        Output file, ``.gif`` or ``.mp4``.
    progress : object with ``update(n)`` and ``describe(desc, total)``, optional
        Told about each frame written (e.g. a :class:`mslab.progress.Progress`).

    Returns
    -------
    Path
    """
    from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter

    path = Path(path)
    springs = scene.springs()
    pairs = springs.springs if springs is not None else np.empty((0, 2), dtype=np.int64)
    colliders = [e for e in scene.system.effects if e.outline() is not None]
    frames = np.unique(np.linspace(0, len(traj.t) - 1, min(max_frames, len(traj.t))).round().astype(int))
    dim = traj.x.shape[2]
    every = traj.x.reshape(-1, dim) if dim == 3 else _as_2d(traj.x.reshape(-1, dim))
    ax, update = _draw(traj.x[frames[0]], pairs, None, scene.system.pinned, colliders, _limits(every), "C0")
    fig = ax.figure
    fig.set_size_inches(5, 4)
    if dim == 3:  # tick labels are most of the drawing time of a 3D frame
        ax.set(xticks=[], yticks=[], zticks=[])
    title = ax.set_title("", fontsize="small")

    def draw(k: int):
        update(traj.x[frames[k]])
        title.set_text(f"{scene.name}  t = {traj.t[frames[k]]:.3f} s  ({traj.stats.method})")
        return ()

    anim = FuncAnimation(fig, draw, frames=len(frames), blit=False)
    writer = FFMpegWriter(fps=fps) if path.suffix == ".mp4" else PillowWriter(fps=fps)
    if progress is not None:
        progress.describe(f"writing {path.suffix[1:]}", total=len(frames))

    def frame_done(i: int, n: int) -> None:
        if progress is not None:
            progress.update(1)

    anim.save(str(path), writer=writer, dpi=72, progress_callback=frame_done)
    plt.close(fig)
    return path
