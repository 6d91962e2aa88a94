"""The plots' canvas and colours, and the checks of their optional dependencies."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from matplotlib.figure import Figure

DPI = 100
ACTION_COLORS = {
    "do_nothing": "#7f8c8d",
    "drink_coffee": "#8e5a2b",
    "drink_beer": "#e0a526",
    "sleep": "#3b5bdb",
}
EXTRA_COLORS = ("#12b886", "#ae3ec9", "#f76707", "#1098ad")
ATTACK_COLOR = "#e03131"
SLEEP_SHADE = "#dbe4ff"
CURVE_COLOR = "#1c7ed6"
VIDEO_SUFFIXES = (".mp4", ".gif")


def require_matplotlib() -> None:
    """Raise ``ImportError`` with the install command if matplotlib is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError as error:
        raise ImportError('plots need matplotlib: pip install "heartpole[plot]"') from error


def require_video_writer(suffix: str) -> None:
    """Raise ``ImportError`` naming what is missing if videos of type ``suffix`` cannot be written: ``.mp4``
    needs imageio and imageio-ffmpeg, ``.gif`` Pillow."""
    try:
        if suffix == ".mp4":
            import imageio  # noqa: F401
            import imageio_ffmpeg  # noqa: F401
        else:
            import PIL  # noqa: F401
    except ImportError as error:
        needed = "imageio and imageio-ffmpeg" if suffix == ".mp4" else "Pillow"
        raise ImportError(f"{suffix} videos need {needed}") from error


def new_figure(width: float, height: float) -> Figure:
    """A new figure on matplotlib's Agg canvas, detached from pyplot (no display, no global state)."""
    require_matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def save_figure(figure: Figure, path: str | Path) -> None:
    """Write ``figure`` as a PNG to ``path``."""
    figure.savefig(path, format="png", dpi=DPI)
