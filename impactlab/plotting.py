"""Figures drawn to PNG files on their own Agg canvas: no pyplot, no backend or style changed."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from functools import wraps
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

import matplotlib
import matplotlib.style
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from impactlab.files import atomic_path

DPI = 110

_PNG_TEXT: ContextVar[dict[str, str] | None] = ContextVar("png_text", default=None)
P = ParamSpec("P")
R = TypeVar("R")


def styled(draw: Callable[P, R]) -> Callable[P, R]:
    """Decorate a drawing function: it draws in matplotlib's default style, whatever the
    user's, which is left as it was (the figures look the same whatever style is set)."""

    @wraps(draw)
    def drawing(*args: P.args, **kwargs: P.kwargs) -> R:
        with matplotlib.style.context("default"):
            return draw(*args, **kwargs)

    return drawing


def subplots(
    nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float], **options: Any
) -> tuple[Figure, Any]:
    """A new figure on an Agg canvas of its own (not pyplot's) and its axes, as
    `pyplot.subplots` returns them."""
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, **options)


@contextmanager
def png_text(text: dict[str, str]) -> Iterator[None]:
    """Within the block, every figure `save_figure` writes carries these PNG text entries."""
    token = _PNG_TEXT.set(text)
    try:
        yield
    finally:
        _PNG_TEXT.reset(token)


def plain(text: object) -> str:
    """Text for a figure drawn as written: a name's `$` never starts math text."""
    return str(text).replace("$", r"\$")


def save_figure(fig: Figure, path: Path) -> Path:
    """Save as PNG (laid out by `tight_layout`) under a temporary name, then rename into
    place. Returns `path`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    fig.set_dpi(DPI)  # laid out at the resolution it is saved at: text measured once
    with atomic_path(path) as tmp:
        fig.tight_layout()
        fig.set_layout_engine(None)  # laid out: drawn once, not twice
        _write_png(canvas, tmp)
    return path


def _write_png(canvas: FigureCanvasAgg, path: Path) -> None:
    """Draw and write the figure as RGB when it is opaque (a third less to compress than
    RGBA: about 35 % less encoding time, 10 % smaller files)."""
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    canvas.draw()  # type: ignore[no-untyped-call]
    rgba = np.asarray(canvas.buffer_rgba())  # type: ignore[no-untyped-call]
    image = Image.fromarray(rgba, "RGBA")
    if bool((rgba[..., 3] == 255).all()):
        image = image.convert("RGB")
    info = PngInfo()
    for key, value in (_PNG_TEXT.get() or {}).items():
        info.add_text(key, value)
    image.save(path, format="png", pnginfo=info, dpi=(canvas.figure.dpi, canvas.figure.dpi))
