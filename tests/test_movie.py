"""Animations as animated PNG images (mslab.plots.movie; issue 27, item 5).

Each decoded frame is compared with the figure drawn directly by the animation's own draw function
(the independent truth: matplotlib's Agg canvas), so the image shows every frame, in order, at the
stated rate, looping or not. ``tests/test_lab.py`` checks in a browser that such an image plays in an
untrusted notebook.
"""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.animation import FuncAnimation  # noqa: E402
from PIL import Image  # noqa: E402

from mslab.plots.movie import animation_image, animation_png  # noqa: E402

N_FRAMES = 6


def _figure():
    fig, ax = plt.subplots(figsize=(3, 2), dpi=60)
    t = np.linspace(0.0, 2 * np.pi, 100)
    (line,) = ax.plot(t, np.sin(t), "-o", ms=2, color="C1")
    ax.plot(t, np.cos(t), color="C0")
    title = ax.set_title("")

    def draw(k: int):
        line.set_ydata(np.sin(t + k))
        title.set_text(f"frame {k}")
        return ()

    return fig, draw


def _drawn(fig, draw, k: int) -> np.ndarray:
    draw(k)
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)


def _decoded(data: bytes) -> list[np.ndarray]:
    image = Image.open(io.BytesIO(data))
    frames = []
    for k in range(image.n_frames):
        image.seek(k)
        frames.append(np.asarray(image.convert("RGB")).astype(int))
    return frames


def test_every_frame_in_order_at_the_rate():
    fig, draw = _figure()
    data = animation_png(FuncAnimation(fig, draw, frames=N_FRAMES), fps=4)
    image = Image.open(io.BytesIO(data))
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and image.format == "PNG" and image.is_animated
    assert image.n_frames == N_FRAMES
    assert image.info["loop"] == 0            # 0: forever
    assert image.info["duration"] == 250      # ms per frame at 4 fps
    decoded = _decoded(data)
    for k in range(N_FRAMES):
        truth = _drawn(fig, draw, k)
        assert decoded[k].shape == truth.shape
        # one palette of 256 for all frames: background and lines exact, a few anti-aliased edge
        # shades move to a neighbouring colour
        error = np.abs(decoded[k] - truth).max(axis=2)
        assert np.mean(error == 0) > 0.95 and np.mean(error > 24) < 0.01, k
        if k:   # each frame is its own, not a repeat of the one before
            assert np.abs(decoded[k] - decoded[k - 1]).max() > 100
    plt.close(fig)


def test_play_once_and_same_bytes_each_time():
    fig, draw = _figure()
    once = animation_png(FuncAnimation(fig, draw, frames=N_FRAMES), fps=2, loop=False)
    again = animation_png(FuncAnimation(fig, draw, frames=N_FRAMES), fps=2, loop=False)
    assert once == again
    info = Image.open(io.BytesIO(once)).info
    assert info["loop"] == 1 and info["duration"] == 500
    plt.close(fig)


def test_notebook_image_closes_the_figure():
    fig, draw = _figure()
    shown = animation_image(FuncAnimation(fig, draw, frames=N_FRAMES), fps=4)
    assert not plt.fignum_exists(fig.number)      # no still copy of the figure under the movie
    assert shown.format == "png" and Image.open(io.BytesIO(shown.data)).n_frames == N_FRAMES
    assert shown._repr_png_() is not None        # shown as image/png (nbval skips its bytes)


@pytest.mark.filterwarnings("ignore:Can not start iterating the frames")
def test_no_frame_is_an_error():
    fig, draw = _figure()
    with pytest.raises(ValueError, match="no frame"):
        animation_png(FuncAnimation(fig, draw, frames=0))
    plt.close(fig)
