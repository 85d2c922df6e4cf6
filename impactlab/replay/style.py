"""Colours of a replay's plots: one per quantity, body or run, readable on the plots' background."""

from __future__ import annotations

from collections.abc import Sequence

Rgb = tuple[int, int, int]

PLOT_BACKGROUND: Rgb = (20, 22, 26)  # set by the layout, so the contrast holds in either theme
MIN_CONTRAST = 3.0  # WCAG 2.1's minimum for graphics (success criterion 1.4.11)
CONTACT: Rgb = (255, 200, 0)  # contact points and forces, in 3D and in the plots
IMPACT: Rgb = (255, 80, 80)
RELEASE: Rgb = (60, 220, 120)
ENERGY: dict[str, Rgb] = {
    "kinetic": (86, 180, 233),
    "potential": (230, 159, 0),
    "total": (240, 110, 200),
}
AXES: dict[str, Rgb] = {"x": (240, 90, 90), "y": (90, 210, 90), "z": (110, 150, 255)}
PALETTE: tuple[Rgb, ...] = (  # runs, and pairs after the first: none grey (as the grid is)
    (230, 159, 0),
    (86, 180, 233),
    (240, 228, 66),
    (240, 110, 200),
    (170, 140, 255),
    (0, 210, 210),
    (150, 230, 80),
)


def luminance(rgb: Sequence[int]) -> float:
    """WCAG 2.1 relative luminance of a 0-255 sRGB colour (0 black .. 1 white)."""
    lin = [c / 255 / 12.92 if c <= 10 else ((c / 255 + 0.055) / 1.055) ** 2.4 for c in rgb[:3]]
    return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]


def contrast(a: Sequence[int], b: Sequence[int]) -> float:
    """WCAG 2.1 contrast ratio of two colours (1 .. 21)."""
    hi, lo = sorted((luminance(a), luminance(b)), reverse=True)
    return (hi + 0.05) / (lo + 0.05)


def readable(rgb: Sequence[int], background: Rgb = PLOT_BACKGROUND) -> Rgb:
    """`rgb`, mixed with white just enough to stand `MIN_CONTRAST` against `background`."""
    for k in range(11):
        mixed = tuple(round(c + (255 - c) * k / 10) for c in rgb[:3])
        if contrast(mixed, background) >= MIN_CONTRAST:
            break
    return mixed  # type: ignore[return-value]
