"""Matplotlib set up for files (Agg backend) and figures saved atomically as PNG."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg

from impactlab.files import atomic_path

if TYPE_CHECKING:
    from matplotlib.figure import Figure

matplotlib.rcParams["text.parse_math"] = False  # a name with `$` is text, never mathtext

__all__ = ["DPI", "plt", "png_text", "save_figure"]

DPI = 110
_PNG_TEXT: ContextVar[dict[str, str] | None] = ContextVar("png_text", default=None)


@contextmanager
def png_text(text: dict[str, str]) -> Iterator[None]:
    """Within the block, every figure `save_figure` writes carries these PNG text entries."""
    token = _PNG_TEXT.set(text)
    try:
        yield
    finally:
        _PNG_TEXT.reset(token)


def save_figure(fig: Figure, path: Path, *, dpi: int = DPI, tight_bbox: bool = False) -> Path:
    """Save as PNG under a temporary name, rename into place, close. Returns `path`.

    The layout is `tight_layout`, or with `tight_bbox` the saved box is cut to the artists
    (for figures whose colour bar spans several axes).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    # laid out at the resolution it is saved at: the layout's text measures are then those
    # of the saving (one renderer, its caches warm) instead of measured again (16% of an
    # energy figure's time; the layout moves by less than a pixel)
    fig.set_dpi(dpi)
    if not tight_bbox:
        fig.tight_layout()
        fig.set_layout_engine(None)  # laid out: saving then draws once, not twice
    try:
        with atomic_path(path) as tmp:
            if tight_bbox:
                fig.savefig(
                    tmp, dpi=dpi, format="png", bbox_inches="tight", metadata=_PNG_TEXT.get()
                )
            else:
                _write_png(fig, tmp)
    finally:
        plt.close(fig)
    return path


def _write_png(fig: Figure, path: Path) -> None:
    """Draw `fig` at its resolution and write it as `savefig` would (the same pixels and PNG
    text entries), as RGB when it is opaque: a third less to compress than RGBA (about
    35% less encoding time, 10% smaller files)."""
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    canvas.draw()  # type: ignore[no-untyped-call]
    rgba = np.asarray(canvas.buffer_rgba())  # type: ignore[no-untyped-call]
    image = Image.fromarray(rgba, "RGBA")
    if bool((rgba[..., 3] == 255).all()):
        image = image.convert("RGB")
    info = PngInfo()
    text = {"Software": f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/"}
    for key, value in {**text, **(_PNG_TEXT.get() or {})}.items():
        info.add_text(key, value)
    image.save(path, format="png", pnginfo=info, dpi=(fig.dpi, fig.dpi))
