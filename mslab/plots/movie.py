"""Animations as animated PNG images: they play in any notebook viewer, trusted or not.

matplotlib's ``to_jshtml`` animations are HTML with scripts; JupyterLab runs no script of an
untrusted notebook (every lesson a student clones is untrusted), so the stored animation shows
a broken image, and its scripts can miss their start when the cell is drawn off screen. An
animated PNG (APNG) is an ordinary ``image/png`` output: JupyterLab, nbviewer, GitHub, VS Code and
any browser play it, without a kernel or trust; a viewer that does not know APNG shows the first
frame. nbval does not compare ``image/png`` bytes (like every figure of the lessons).
"""

from __future__ import annotations

import io
from typing import TYPE_CHECKING, Any

from matplotlib.animation import AbstractMovieWriter

if TYPE_CHECKING:
    from matplotlib.animation import Animation
    from PIL import Image as PILImage


class _FrameGrabber(AbstractMovieWriter):
    """A movie writer that keeps the drawn frames as RGB images in memory (no file, no tool)."""

    def setup(self, fig: Any, outfile: Any, dpi: float | None = None) -> None:
        super().setup(fig, outfile, dpi=dpi)
        self.frames: list[PILImage.Image] = []

    def grab_frame(self, **savefig_kwargs) -> None:
        from PIL import Image

        buffer = io.BytesIO()
        self.fig.savefig(buffer, format="rgba", dpi=self.dpi, **savefig_kwargs)
        rgba = Image.frombuffer("RGBA", self.frame_size, buffer.getbuffer(), "raw", "RGBA", 0, 1)
        self.frames.append(rgba.convert("RGB"))

    def finish(self) -> None:
        pass


def _grab(anim: Animation, dpi: float | None) -> _FrameGrabber:
    grabber = _FrameGrabber()
    anim.save("animation.png", writer=grabber, dpi=dpi)   # the name is unused: frames stay in memory
    if not grabber.frames:
        raise ValueError("the animation drew no frame")
    return grabber


def _encode(frames: list[PILImage.Image], fps: float, loop: bool) -> bytes:
    from PIL import Image

    # one palette for all frames (APNG has a single palette): the frames stacked into one strip,
    # quantized at once (median cut, no dithering) and cut apart again. Mapping each frame to a
    # palette separately would shift the white background by a few levels.
    width, height = frames[0].size
    strip = Image.new("RGB", (width, height * len(frames)))
    for k, frame in enumerate(frames):
        strip.paste(frame, (0, k * height))
    strip = strip.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    indexed = [strip.crop((0, k * height, width, (k + 1) * height)) for k in range(len(frames))]
    out = io.BytesIO()
    indexed[0].save(out, format="PNG", save_all=True, append_images=indexed[1:],
                    duration=round(1000.0 / fps), loop=0 if loop else 1, optimize=True)
    return out.getvalue()


def animation_png(anim: Animation, fps: float = 5.0, loop: bool = True, dpi: float | None = None) -> bytes:
    """Draw every frame of a matplotlib animation into one animated PNG (APNG).

    Parameters
    ----------
    anim : matplotlib.animation.Animation
        E.g. a ``FuncAnimation(fig, draw, frames=n)``; its figure is drawn ``n`` times.
    fps : float
        Frames per second of the image.
    loop : bool
        Play forever (True) or once, stopping on the last frame (False).
    dpi : float, optional
        Resolution of the frames; default the figure's own.

    Returns
    -------
    bytes
        The PNG file. Colours are quantized to one palette of at most 256 shared by all frames
        (a paletted frame is a third of an RGB one; a plot has few colours); Pillow stores each
        frame after the first as the rectangle that changed.
    """
    return _encode(_grab(anim, dpi).frames, fps, loop)


def animation_image(anim: Animation, fps: float = 5.0, loop: bool = True, dpi: float | None = None) -> Any:
    """Show a matplotlib animation in a notebook as an animated PNG image (plays untrusted, no kernel).

    Closes the animation's figure, so the notebook shows the animation only, not a still figure too.

    Parameters
    ----------
    anim, fps, loop, dpi
        As in :func:`animation_png`.

    Returns
    -------
    IPython.display.Image
        Display it (``display(...)``) or leave it as a cell's last expression.

    Examples
    --------
    >>> anim = FuncAnimation(fig, draw, frames=len(times))        # doctest: +SKIP
    >>> display(animation_image(anim, fps=4, loop=False))         # doctest: +SKIP
    """
    import matplotlib.pyplot as plt
    from IPython.display import Image

    grabber = _grab(anim, dpi)
    plt.close(grabber.fig)
    return Image(data=_encode(grabber.frames, fps, loop), format="png")
