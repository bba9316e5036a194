"""Mode-shape pictures: PNG (one panel per mode) and animated GIF, drawn with matplotlib.

Each panel shows the stick figure of :mod:`pinlin.stick_figure` at q0 (grey) and displaced
along the mode (a real shape at +a and -a, a complex one at several phases of its cycle),
projected orthographically on the mode's plane of largest displacement
(:func:`pinlin.figure_view.best_view`; the axis labels say which plane). The title gives the
mode's row in the mode table, its frequency and damping ratio, and the amplitude a: the
excursion of the shape's largest coordinate [rad or m]. Loop closures are marked with an open
circle; the world origin a mechanism or a fixed base hangs from with a black triangle.

Figures are built on matplotlib's ``Figure`` with the Agg canvas (no pyplot state, no display
needed) and written atomically (:mod:`pinlin.files`). GIF frames are quantized to a palette
with Pillow (a matplotlib dependency).
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .coordinates import linear_coordinates
from .exceptions import ArgumentError, ModelFileError
from .fields import show
from .figure_view import View, best_view
from .files import (
    GIF_COMMENT,
    PNG_METADATA,
    as_path,
    check_file_target,
    write_bytes_atomic,
)
from .modal import ModalAnalysis
from .stick_figure import AXIS_LENGTH, ModeMotion, Skeleton, mode_motion

#: Modes drawn by default: the first DEFAULT_COUNT that are neither rigid nor constraint modes
#: (rigid ones where there are no others).
DEFAULT_COUNT = 4
#: Frames per cycle of an animation.
GIF_FRAMES = 24
#: Duration of one animation frame [ms].
GIF_FRAME_MS = 60
PANEL_SIZE = 3.4  # [inch]
REST_COLOR = "0.6"
#: Resolutions a picture may be drawn at [dots per inch] (a 9-inch figure at 600 dpi is
#: already 5400 pixels wide, ~100 MB while drawn).
DPI_MIN, DPI_MAX = 10, 600
#: Colours of the phases of a complex mode (matplotlib's C0, C1, C2, C3, C4, C6).
PHASE_COLORS = ("C0", "C1", "C2", "C3", "C4", "C6")


def default_modes(modes: ModalAnalysis, count: int = DEFAULT_COUNT) -> list[int]:
    """Eigenvalue indices of the first ``count`` modes worth drawing (module constant)."""
    keep = modes.modes()
    moving = [i for i in keep if modes.kind(i) not in ("rigid", "constraint")]
    if not moving:
        moving = [i for i in keep if modes.kind(i) != "constraint"]
    drawn: list[int] = []
    for i in moving:      # +-sigma of an unstable pair move alike: draw the shape once
        if not any(_mirrored(modes, i, j) for j in drawn):
            drawn.append(i)
    return drawn[:count]


def _mirrored(modes: ModalAnalysis, i: int, j: int) -> bool:
    """Whether real eigenvalues i and j are +-sigma with the same shape (to rounding)."""
    a, b = modes.eigenvalues[i], modes.eigenvalues[j]
    if a.imag or b.imag or abs(a + b) > 1e-9 * max(abs(a), abs(b)):
        return False
    si, sj = modes.shapes[:, i], modes.shapes[:, j]
    return bool(np.allclose(si, sj, rtol=0, atol=1e-9) or np.allclose(si, -sj, rtol=0,
                                                                      atol=1e-9))


def _indices(modes: ModalAnalysis, indices: Sequence[int] | int | None) -> list[int]:
    if indices is None:
        chosen = default_modes(modes)
        if not chosen:
            raise ArgumentError("indices", f"model '{modes.model.name}' has no mode to draw")
        return chosen
    try:
        items = [indices] if isinstance(indices, int | np.integer) else list(indices)
    except TypeError:
        items = [indices]
    if not items:
        raise ArgumentError("indices", "expected one or more eigenvalue indices, got none")
    for item in items:
        if isinstance(item, bool) or not isinstance(item, int | np.integer):
            raise ArgumentError("indices", f"expected eigenvalue indices (int), got "
                                           f"{show(item)}")
    out = [int(k) for k in items]
    n = len(modes.eigenvalues)
    first = {}   # each index as its mode's first eigenvalue (a conjugate names its pair)
    keep = modes.modes()
    for k in out:
        if not 0 <= k < n:
            continue   # the picture names the index it cannot draw
        mode = k if k in keep else k - 1
        if mode in first:
            raise ArgumentError("indices", f"indices {first[mode]} and {k} name the same mode "
                                           f"(mode {keep.index(mode) + 1}): it would be drawn "
                                           "twice")
        first[mode] = k
    return out


def _check_dpi(dpi: object) -> float:
    """``dpi`` [dots per inch] within [DPI_MIN, DPI_MAX]."""
    if isinstance(dpi, bool) or not isinstance(dpi, int | float | np.integer | np.floating) \
            or not DPI_MIN <= dpi <= DPI_MAX:
        raise ArgumentError("dpi", f"expected a resolution from {DPI_MIN} to {DPI_MAX} dots per "
                                   f"inch, got {show(dpi)}")
    return float(dpi)


def unit_of(system, modes: ModalAnalysis, motion: ModeMotion) -> tuple[str, str]:
    """(coordinate name, unit) of the shape's largest entry: the coordinate whose excursion
    the amplitude is."""
    k = int(np.argmax(np.abs(modes.shapes[:, motion.index])))
    name = modes.coordinate_names[k]
    if name not in system.coordinate_names:
        return name, "(rad or m)"
    linear = linear_coordinates(system)[system.coordinate_names.index(name)]
    return name, "m" if linear else "rad"


def title(system, modes: ModalAnalysis, motion: ModeMotion) -> str:
    """Two title lines: the mode label, then the amplitude and its coordinate."""
    name, unit = unit_of(system, modes, motion)
    return f"{motion.label}\na = {motion.amplitude:.3g} {unit} on {name}"


def draw_motion(ax, motion: ModeMotion, view: View, figures: Sequence[int] | None = None,
                legend: bool = True) -> list:
    """Draw the rest figure and the figures ``figures`` (indices into ``motion.figures``;
    default all) of ``motion`` on ``ax`` in ``view``; returns the moving line artists."""
    rest = view.project(motion.rest.points)
    _draw_figure(ax, motion.rest, rest, REST_COLOR, "-", 3.0, zorder=1, label="q0")
    chosen = range(len(motion.figures)) if figures is None else figures
    triads = motion.turning()
    artists = []
    for k in chosen:
        fig = motion.figures[k]
        color, style, label = _style(motion, k)
        artists += _draw_figure(ax, fig, view.project(fig.points), color, style, 1.6, zorder=3,
                                label=label)
        artists += draw_triads(ax, fig, view, triads, AXIS_LENGTH * motion.rest.size)
    if triads:
        draw_triads(ax, motion.rest, view, triads, AXIS_LENGTH * motion.rest.size, rest=True)
    if legend:
        ax.legend(fontsize=6, loc="best", framealpha=0.6)
    xlabel, ylabel = view.labels
    ax.set_xlabel(xlabel, fontsize=7)
    ax.set_ylabel(ylabel, fontsize=7)
    ax.tick_params(labelsize=6)
    ax.set_aspect("equal", adjustable="box")
    ax.grid(True, alpha=0.25)
    return artists


def draw_triads(ax, fig, view: View, points: Sequence[int], length: float,
                rest: bool = False) -> list:
    """The frames of ``points`` of ``fig`` as short x, y, z axes (red, green, blue; paler at
    rest) of ``length`` [m]; returns the artists."""
    artists = []
    for k in points:
        origin = view.project(fig.points[k])
        for axis, color in enumerate(("#d62728", "#2ca02c", "#1f77b4")):
            tip = view.project(fig.points[k] + length * fig.rotations[k][:, axis])
            artists += ax.plot([origin[0], tip[0]], [origin[1], tip[1]], "-", color=color,
                               lw=1.0 if rest else 1.4, alpha=0.35 if rest else 0.9, zorder=4)
    return artists


def _style(motion: ModeMotion, k: int) -> tuple[str, str, str]:
    theta = float(motion.phases[k])
    if not motion.complex and len(motion.phases) == 2:
        plus = math.cos(theta) >= 0
        return ("C0", "-", "+a") if plus else ("C3", "--", "-a")
    if len(motion.phases) <= len(PHASE_COLORS):
        color = PHASE_COLORS[k]
    else:
        import matplotlib

        color = matplotlib.colors.to_hex(
            matplotlib.colormaps["hsv"]((theta / (2 * np.pi)) % 1.0 * 0.9))
    return color, "-", f"{math.degrees(theta) % 360:.0f} deg"


def _draw_figure(ax, fig, xy: np.ndarray, color: str, style: str, width: float, zorder: int,
                 label: str) -> list:
    """One figure: its links as one polyline (NaN between links), its points, the world
    origin and the loop closures; returns the artists."""
    segments = np.full((3 * len(fig.links), 2), np.nan)
    segments[0::3] = xy[fig.links[:, 0]]
    segments[1::3] = xy[fig.links[:, 1]]
    (lines,) = ax.plot(segments[:, 0], segments[:, 1], style, color=color, lw=width,
                       zorder=zorder, solid_capstyle="round", label=label or None)
    joints = [k for k, kind in enumerate(fig.kinds) if kind != "world"]
    (dots,) = ax.plot(xy[joints, 0], xy[joints, 1], "o", color=color, ms=3.5, zorder=zorder + 1)
    artists = [lines, dots]
    world = [k for k, kind in enumerate(fig.kinds) if kind == "world"]
    if world:
        artists += ax.plot(xy[world, 0], xy[world, 1], "^", color="k", ms=6, zorder=zorder + 2)
    if len(fig.closures):
        artists += ax.plot(xy[fig.closures[:, 0], 0], xy[fig.closures[:, 0], 1], "o",
                           mfc="none", mec=color, ms=7, zorder=zorder + 1)
    return artists


def _limits(motion: ModeMotion, view: View) -> tuple[tuple[float, float], tuple[float, float]]:
    """Square limits (equal spans) around every drawn point, with a margin [m]."""
    xy = np.vstack([view.project(f.points) for f in (motion.rest, *motion.figures)])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    half = 0.58 * max(float((hi - lo).max()), 1e-3)
    mid = 0.5 * (lo + hi)
    return (mid[0] - half, mid[0] + half), (mid[1] - half, mid[1] + half)


def _grid(count: int):
    """A figure with ``count`` panels, laid out by hand (fixed margins in inches: no layout
    engine, which would cost a draw per picture)."""
    from matplotlib.figure import Figure

    cols = min(count, 2 if count == 4 else 3)
    rows = math.ceil(count / cols)
    width, height = PANEL_SIZE, PANEL_SIZE + 0.2            # one panel [inch]
    top, left, right, bottom, title = 0.3, 0.55, 0.12, 0.42, 0.42
    fig_w, fig_h = width * cols, height * rows + top
    fig = Figure(figsize=(fig_w, fig_h))
    axes = []
    for k in range(count):
        row, col = divmod(k, cols)
        x0 = col * width + left
        y0 = fig_h - top - (row + 1) * height + bottom
        axes.append(fig.add_axes((x0 / fig_w, y0 / fig_h, (width - left - right) / fig_w,
                                  (height - bottom - title) / fig_h)))
    return fig, axes


def _motions(scene, modes: ModalAnalysis, indices, amplitude, phases=None
             ) -> list[ModeMotion]:
    from .linearization import _system

    if not isinstance(modes, ModalAnalysis):
        raise ArgumentError("modes", f"expected a pinlin.modal(...) result, got "
                                     f"{type(modes).__name__}")
    system = _system(scene)
    skeleton = Skeleton(system)
    return [mode_motion(system, modes, i, amplitude=amplitude, phases=phases,
                        skeleton=skeleton) for i in _indices(modes, indices)]


def picture(scene, modes: ModalAnalysis, indices: Sequence[int] | int | None = None, *,
            amplitude: float | None = None, dpi: float = 90, palette: bool = False) -> bytes:
    """A PNG (bytes) with one panel per mode.

    Args:
        scene: The scene (or System, or scene name) the analysed model was made from.
        modes: ``pinlin.modal(model)``.
        indices: Eigenvalue indices to draw (a conjugate's index means its pair); default
            :func:`default_modes`.
        amplitude: a [rad or m] for every mode; default per mode
            (:func:`pinlin.stick_figure.readable_amplitude`).
        dpi: Resolution [dots per inch].
        palette: Store the PNG with a 64-colour palette (about a third of the size; for
            pictures committed to a repository).
    """
    from .linearization import _system

    dpi = _check_dpi(dpi)
    system = _system(scene)
    motions = _motions(system, modes, indices, amplitude)
    fig, axes = _grid(len(motions))
    for ax, motion in zip(axes, motions, strict=True):
        view = best_view(motion)
        draw_motion(ax, motion, view)
        xlim, ylim = _limits(motion, view)
        ax.set_xlim(*xlim)
        ax.set_ylim(*ylim)
        ax.set_title(title(system, modes, motion), fontsize=8)
    fig.suptitle(f"Modes of '{modes.model.name}' (grey: q0)", fontsize=9, y=0.995,
                 va="top")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata=PNG_METADATA)
    if not palette:
        return buf.getvalue()
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    image = Image.open(io.BytesIO(buf.getvalue())).convert("RGB")
    out = io.BytesIO()
    info = PngInfo()
    info.add_text(*next(iter(PNG_METADATA.items())))
    image.quantize(colors=64, dither=0).save(out, format="PNG", optimize=True, pnginfo=info)
    return out.getvalue()


def animation(scene, modes: ModalAnalysis, indices: Sequence[int] | int | None = None, *,
              amplitude: float | None = None, frames: int = GIF_FRAMES, dpi: float = 72
              ) -> bytes:
    """An animated GIF (bytes, looping): the panels of :func:`picture`, each mode's figure
    moving through ``frames`` phases of one cycle, q(theta) = the configuration at
    a Re(e^{i theta} phi) (:func:`pinlin.stick_figure.mode_motion`)."""
    from PIL import Image

    from .linearization import _system

    if isinstance(frames, bool) or not isinstance(frames, int) or not 2 <= frames <= 360:
        raise ArgumentError("frames", f"expected 2 to 360 frames per cycle, got {frames!r}")
    dpi = _check_dpi(dpi)
    system = _system(scene)
    phases = np.arange(frames) * 2 * np.pi / frames
    motions = _motions(system, modes, indices, amplitude, phases)
    fig, axes = _grid(len(motions))
    moving = []
    triads = {id(m): m.turning() for m in motions}
    for ax, motion in zip(axes, motions, strict=True):
        view = best_view(motion)
        draw_motion(ax, motion, view, figures=[], legend=False)
        xlim, ylim = _limits(motion, view)
        ax.set_xlim(*xlim)
        ax.set_ylim(*ylim)
        ax.set_title(title(system, modes, motion), fontsize=8)
        moving.append((ax, motion, view, []))
    fig.suptitle(f"Modes of '{modes.model.name}' (grey: q0)", fontsize=9, y=0.995,
                 va="top")
    fig.set_dpi(dpi)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()                       # the still parts once; each frame blits onto them
    background = canvas.copy_from_bbox(fig.bbox)
    images = []
    for k in range(frames):
        canvas.restore_region(background)
        for ax, motion, view, artists in moving:
            for artist in artists:
                artist.remove()
            artists.clear()
            f = motion.figures[k]
            artists += _draw_figure(ax, f, view.project(f.points), "C0", "-", 1.8, zorder=3,
                                    label="")
            artists += draw_triads(ax, f, view, triads[id(motion)],
                                   AXIS_LENGTH * motion.rest.size)
            for artist in artists:
                ax.draw_artist(artist)
        rgba = np.asarray(canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[..., :3]).quantize(colors=64, dither=0))
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:],
                   duration=GIF_FRAME_MS, loop=0, optimize=True, comment=GIF_COMMENT)
    return buf.getvalue()


def check_target(path: object, suffix: str, option: str = "path") -> Path:
    """``path`` as a Path that can be written and ends in ``suffix``.

    Raises:
        ArgumentError: not a path.
        ModelFileError: another suffix, a folder, or a folder that does not exist.
    """
    path = as_path(path, option)
    if path.is_dir():
        raise ModelFileError(path, f"is a folder; expected a {suffix} file name")
    if path.suffix.lower() != suffix:
        kind = "picture" if suffix == ".png" else "animation"
        raise ModelFileError(path, f"expected a {suffix} file for the mode {kind}, got "
                                   f"'{path.suffix or 'no suffix'}'")
    return check_file_target(path)


def plot_modes(scene, modes: ModalAnalysis, path: str | Path,
               indices: Sequence[int] | int | None = None, *, amplitude: float | None = None,
               dpi: float = 90) -> Path:
    """Write :func:`picture` to ``path`` (``.png``) atomically; returns the path.

    Raises:
        ModelFileError: ``path`` does not end in .png or cannot be written (checked first).
        ArgumentError, ModelError, AssemblyError: as :func:`pinlin.stick_figure.mode_motion`.
    """
    path = check_target(path, ".png")
    write_bytes_atomic(path, picture(scene, modes, indices, amplitude=amplitude, dpi=dpi))
    return path


def animate_modes(scene, modes: ModalAnalysis, path: str | Path,
                  indices: Sequence[int] | int | None = None, *,
                  amplitude: float | None = None, frames: int = GIF_FRAMES, dpi: float = 72
                  ) -> Path:
    """Write :func:`animation` to ``path`` (``.gif``) atomically; returns the path.

    Raises:
        ModelFileError: ``path`` does not end in .gif or cannot be written (checked first).
    """
    path = check_target(path, ".gif")
    write_bytes_atomic(path, animation(scene, modes, indices, amplitude=amplitude,
                                       frames=frames, dpi=dpi))
    return path


__all__ = ["animate_modes", "animation", "default_modes", "draw_motion", "picture",
           "plot_modes", "title"]
