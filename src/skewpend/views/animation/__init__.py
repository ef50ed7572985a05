"""3-D animation of a simulated trajectory: MP4 (H.264) or GIF.

Every row of a :class:`skewpend.Trajectory` is one frame, so the frames are exactly the
dense-output states at the frame times ``k * speed / fps`` (make the trajectory with
``skewpend.simulate(params, y0, duration * speed, dt_out=speed / fps)``).

The geometry of a frame comes from the model's generated kinematics only -- the hinges' positions
(:func:`skewpend.views.drawing.link_points`: each link drawn from its hinge to the next one, the last to its
rod's end ``tr.tips()``) and the hinge axes ``tr.axes()`` (``n1`` and ``e = P1·e0``); nothing here recomputes
the kinematics.  :func:`frame_scene` returns that
geometry in world coordinates exactly as it is drawn, so it can be checked against the
model and against the projected artists of :class:`FrameRenderer`.

Coordinates: the world basis ``i, j, k`` has ``j`` pointing down.  The plot shows
``(X, Y, Z) = (x, z, -y)`` (a proper rotation: the pendulum hangs down the screen, the first
hinge axis ``k`` is the plot's horizontal ``Y``); see :func:`world_to_plot`.

Rendering is Matplotlib 3-D on an Agg canvas (object-oriented, no pyplot): the static parts are drawn
once, each frame restores that background and draws only the moving artists (:class:`FrameRenderer`).
"""

from __future__ import annotations

from contextlib import suppress
from pathlib import Path
from typing import Callable, Optional, Sequence, Tuple

import numpy as np

from ... import checks
from ...errors import ParameterError, SkewpendError
from ...io import atomic_path
from ...progress import detail as say_detail
from .renderer import FrameRenderer
from .scene import (DEFAULT_DPI, DEFAULT_SIZE, DEFAULT_TRAIL, DEFAULT_VIEW, MIN_EDGE, SUFFIXES, FrameScene,  # noqa: F401
                    check_frame_size, check_view, choose_view, eye, frame_scene, plot_to_world, world_to_plot)

__all__ = ["animate", "frame_scene", "FrameScene", "FrameRenderer", "world_to_plot", "plot_to_world", "choose_view",
           "check_frame_times", "check_output", "SUFFIXES", "DEFAULT_SIZE", "DEFAULT_DPI", "DEFAULT_TRAIL",
           "DEFAULT_VIEW", "eye"]


def check_frame_times(t, fps: float, speed: float) -> None:
    """Refuse a trajectory whose rows are not exactly the frame times ``k * speed / fps``."""
    t = np.asarray(t, dtype=float)
    step = speed / fps
    grid = np.arange(t.size) * step
    tol = 1e-9 * step + 8.0 * np.finfo(float).eps * np.abs(grid)
    bad = np.nonzero(~(np.abs(t - grid) <= tol))[0]
    if bad.size:
        k = int(bad[0])
        raise ParameterError(f"the trajectory's rows are not the frame times k*speed/fps = k*{step:.6g} s "
                             f"(fps={fps:g}, speed={speed:g}): t[{k}] = {t[k]:.9g} s, expected {grid[k]:.9g} s; "
                             "simulate with dt_out=speed/fps")


def check_output(out) -> Path:
    """The output path: a known suffix, not a directory, in an existing writable directory."""
    from ...io import check_output_path

    return check_output_path(out, SUFFIXES, option="animation output")


def _ffmpeg():
    try:
        import imageio_ffmpeg
    except ImportError:
        raise SkewpendError("MP4 output needs the ffmpeg that the imageio-ffmpeg wheel ships: pip install "
                            "imageio-ffmpeg (a dependency of skewpend); or write a .gif") from None
    return imageio_ffmpeg


def _write_mp4(tmp: Path, frames, size: Tuple[int, int], fps: float) -> None:
    """H.264 through the wheel's ffmpeg, run here (not imageio's writer, which lets ffmpeg print
    to the terminal and returns as if done when ffmpeg failed): frames on its stdin, its messages
    kept in a temporary file and reduced to one line on a failure -- a full disk is "cannot write
    OUT: No space left on device" --, its exit status checked; an error or Ctrl-C kills it."""
    import subprocess
    import tempfile
    from fractions import Fraction

    exe = _ffmpeg().get_ffmpeg_exe()
    w, h = size
    # libx264 (the wheel's ffmpeg has it); the temporary file's name has no .mp4: say the format
    cmd = [exe, "-y", "-nostdin", "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{w}x{h}", "-pix_fmt", "rgb24",
           "-r", str(Fraction(float(fps)).limit_denominator()), "-i", "-", "-an", "-vcodec", "libx264",
           "-pix_fmt", "yuv420p", "-v", "error", "-crf", "18", "-preset", "veryfast", "-movflags", "+faststart",
           "-f", "mp4", str(tmp)]
    with tempfile.TemporaryFile() as log:  # ffmpeg's messages: never to the terminal
        try:
            proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=log,
                                    start_new_session=True)  # Ctrl-C at the terminal is ours to handle
        except OSError as exc:
            raise SkewpendError(f"cannot run ffmpeg ({exe}): {exc.strerror or exc}") from None
        try:
            with suppress(BrokenPipeError):  # ffmpeg stopped: its status and messages say why
                for frame in frames:
                    proc.stdin.write(np.ascontiguousarray(frame, dtype=np.uint8).tobytes())
                proc.stdin.close()
            status = proc.wait()
        finally:
            if proc.poll() is None:  # an error or Ctrl-C while writing: stop it at once
                proc.kill()
                proc.wait()
            if proc.stdin is not None and not proc.stdin.closed:
                with suppress(OSError):
                    proc.stdin.close()
        log.seek(0)
        messages = log.read().decode("utf-8", "replace")
    if status != 0 or not tmp.exists() or tmp.stat().st_size == 0:
        import errno

        raise OSError(errno.ENOSPC if "No space left on device" in messages else errno.EIO,
                      _ffmpeg_reason(messages, status))


def _ffmpeg_reason(messages: str, status: int) -> str:
    """One line for ffmpeg's failure: the system's reason when it gave one (a full disk), else
    its last message."""
    import re

    for reason in ("No space left on device", "Disk quota exceeded", "Permission denied", "Read-only file system",
                   "File too large", "Input/output error"):
        if reason in messages:
            return reason
    lines = [re.sub(r"^\[[^\]]*\]\s*", "", ln).strip() for ln in messages.splitlines() if ln.strip()]
    last = lines[-1] if lines else "no message"
    return f"ffmpeg failed (exit status {status}: {last})"


def _write_gif(tmp: Path, frames, fps: float, sample: np.ndarray) -> None:
    """GIF through Pillow: one global palette (from ``sample``, a few frames stacked), no
    dithering (flat shaded colours), ``1000 / fps`` ms per frame, looping."""
    from PIL import Image

    palette = Image.fromarray(sample, "RGB").quantize(colors=255, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    # the background stays pure white: the entry white maps to becomes exactly white
    entries = palette.getpalette()
    white = Image.new("RGB", (1, 1), (255, 255, 255)).quantize(palette=palette, dither=Image.Dither.NONE).getpixel((0, 0))
    entries[3 * white : 3 * white + 3] = [255, 255, 255]
    palette.putpalette(entries)

    def images():
        for frame in frames:
            yield Image.fromarray(frame, "RGB").quantize(palette=palette, dither=Image.Dither.NONE)

    it = images()
    first = next(it)
    first.save(tmp, format="GIF", save_all=True, append_images=it, duration=1000.0 / fps, loop=0)


def animate(
    tr,
    out,
    *,
    fps: float = 30.0,
    speed: float = 1.0,
    trail: float = DEFAULT_TRAIL,
    size: Sequence[int] = DEFAULT_SIZE,
    dpi: float = DEFAULT_DPI,
    view: Optional[Tuple[float, float]] = None,
    progress: Optional[Callable[[int, int], None]] = None,
) -> Path:
    """Render every row of ``tr`` as one frame and write ``out`` (``.mp4`` or ``.gif``).

    ``tr`` must be sampled exactly at the frame times ``k * speed / fps`` (make it with
    ``skewpend.simulate(params, y0, duration * speed, dt_out=speed / fps)``), else
    :class:`~skewpend.ParameterError`.  ``fps``: frames per second of the video; ``speed``:
    seconds of motion per second of video (0.5 = slow motion); ``trail``: seconds of motion the
    fading trail of rod 2's tip covers (0: none); ``size``: (width, height) in pixels (even for
    MP4); ``dpi``: scales text and lines; ``view``: camera (elev, azim) in degrees, plot
    coordinates (default: :func:`choose_view`); ``progress(done, total)`` is called after each
    frame.

    MP4 is H.264 (yuv420p) through the ffmpeg of the ``imageio-ffmpeg`` wheel; GIF goes through
    Pillow (``1000 / fps`` ms per frame -- GIF stores hundredths of a second --, looping).  The
    file is written to a temporary file beside ``out`` and renamed at the end; on any error or
    Ctrl-C the temporary file is removed and ``out`` is untouched.  Returns ``Path(out)``.
    """
    from ...numeric.simulation import Trajectory

    if not isinstance(tr, Trajectory):
        raise ParameterError(f"tr must be a skewpend.Trajectory (from skewpend.simulate), got {type(tr).__name__}")
    path = check_output(out)
    fps = checks.positive("fps", fps)
    speed = checks.positive("speed", speed)
    w, h = check_frame_size(size)
    fmt = path.suffix.lower()
    if fmt == ".mp4" and (w % 2 or h % 2):
        raise ParameterError(f"MP4 (H.264, yuv420p) needs an even width and height, got {w}x{h}")
    checks.progress_callable(progress)
    if view is not None:
        view = check_view(view)
    checks.positive("dpi", dpi)
    checks.finite_seconds("trail", trail)
    if fmt == ".mp4":
        _ffmpeg()
    if not getattr(tr, "kept", True):
        raise ParameterError("the trajectory kept only its first and last rows (keep=False); animate needs every row")
    check_frame_times(tr.t, fps, speed)

    say_detail("setting up the scene (Matplotlib)")  # the checks passed: the work begins (issue 51: no silence)
    renderer = FrameRenderer(tr, size=(w, h), dpi=dpi, trail=trail, speed=speed, view=view)
    total = renderer.geometry.t.size

    def frames():
        for k in range(total):
            say_detail(f"frame {k + 1} of {total}")
            renderer.draw(k)
            yield renderer.rgb()
            if progress is not None:
                progress(k + 1, total)
        say_detail(f"finishing the {fmt[1:].upper()} file")

    try:
        with atomic_path(path) as tmp:
            if fmt == ".mp4":
                _write_mp4(tmp, frames(), (w, h), fps)
            else:
                sample = []
                picked = sorted({0, total // 3, (2 * total) // 3, total - 1})
                for i, k in enumerate(picked, 1):  # for the palette
                    say_detail(f"the GIF's palette: frame {i} of {len(picked)}")
                    renderer.draw(k)
                    sample.append(renderer.rgb())
                _write_gif(tmp, frames(), fps, np.concatenate(sample, axis=0))
    finally:
        renderer.close()
    return path
