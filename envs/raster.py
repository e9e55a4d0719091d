"""A small anti-aliased rasterizer in numpy: the envs' ``rgb_array`` frames are drawn with it.

A :class:`Raster` is a white ``(height, width, 3)`` uint8 image drawn on in pixel coordinates
``(column, row)`` (the pixel ``(c, r)`` covers ``[c, c + 1) x [r, r + 1)``; rows grow downwards);
a :class:`WorldToPixels` maps a box of the plane [m] onto a rectangle of it with equal scales on
both axes. A stroke is drawn by sampling its polylines every :data:`SAMPLE_SPACING` pixels and
stamping a disc of the stroke's width at each sample: the pixel's coverage, ``1`` within the half
width and falling to ``0`` one pixel beyond, is looked up by where the sample falls inside its
pixel (to an eighth of a pixel), and the strongest coverage of a pixel sets how much of the
stroke's colour it takes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from ilc_steering.envs.glyphs import BASELINE, text_mask

__all__ = ["RGB", "SAMPLE_SPACING", "Raster", "WorldToPixels"]

Array = npt.NDArray[np.float64]
RGB = tuple[int, int, int]

SAMPLE_SPACING = 0.5
"""Pixels between the samples of a stroke up to 2 pixels wide (wider ones: a quarter of the width),
close enough that the coverage along a stroke's edge varies by less than a tenth."""
SUBPIXEL, SHIFT = 8, 3
"""Positions of a sample inside its pixel, per axis (``2**SHIFT``), each with a precomputed stamp."""
PAD = 8
"""Pixels of the coverage layer beyond each side of the image: the widest stamp's reach."""
NOTHING_MARKED = (2**30, 2**30, -1, -1)
"""The (left, top, right, bottom) pixels of the samples marked since the last fill: none."""


@lru_cache(maxsize=16)
def _stamp(width: float, stride: int) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.float32]]:
    """The flat offsets ``(K,)`` (rows of ``stride`` pixels) of the pixels a disc of diameter ``width``
    [px] can reach from its sample's pixel, and their coverage ``(SUBPIXEL**2, K)`` by where the
    sample falls in that pixel (row-major eighths)."""
    reach = int(np.ceil(width / 2 + 1.0))
    if reach > PAD:
        raise ValueError(f"a stroke is at most {2 * PAD - 2} pixels wide, got {width}")
    dr, dc = (a.ravel() for a in np.mgrid[-reach : reach + 1, -reach : reach + 1])
    fy, fx = ((a.ravel() + 0.5) / SUBPIXEL for a in np.mgrid[:SUBPIXEL, :SUBPIXEL])
    # Distance from each offset pixel's centre to the sample at (fx, fy) in its own pixel.
    distance = np.hypot(dr[None] + 0.5 - fy[:, None], dc[None] + 0.5 - fx[:, None])
    coverage = np.clip(width / 2 + 0.5 - distance, 0.0, 1.0).astype(np.float32)
    used = np.any(coverage > 0, axis=0)
    return (dr * stride + dc)[used], np.ascontiguousarray(coverage[:, used])


class WorldToPixels:
    """The map of the world box ``lower`` to ``upper`` [m] (each ``(x, y)``) onto the pixel rectangle
    ``(left, top, right, bottom)``, one scale for both axes: the box grows along one axis to fill
    the rectangle, centred (as matplotlib's equal axes with ``adjustable="datalim"``)."""

    def __init__(self, lower: Array, upper: Array, rectangle: tuple[int, int, int, int]) -> None:
        left, top, right, bottom = rectangle
        span = np.maximum(np.asarray(upper, dtype=np.float64) - lower, 1e-12)
        self.scale = float(min((right - left) / span[0], (bottom - top) / span[1]))
        """Pixels per metre."""
        centre = (np.asarray(lower, dtype=np.float64) + upper) / 2
        half = np.array([right - left, bottom - top]) / (2 * self.scale)
        self.lower, self.upper = centre - half, centre + half
        """The world box the rectangle shows [m]."""
        self._factor = np.array([self.scale, -self.scale])
        self._origin = np.array([left, bottom]) - self.lower * self._factor

    def __call__(self, points: Array) -> Array:
        """Pixel ``(column, row)`` of world points ``(..., 2)`` [m]."""
        return np.asarray(points, dtype=np.float64) * self._factor + self._origin


class Raster:
    """A white ``(height, width, 3)`` uint8 image, drawn on in pixel coordinates."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.image = np.full((height, width, 3), 255, dtype=np.uint8)
        self._pixels = self.image.reshape(-1, 3)
        self._coverage = np.zeros((height + 2 * PAD) * (width + 2 * PAD), dtype=np.float32)
        self._marked = NOTHING_MARKED

    def stroke(
        self,
        lines: Sequence[Array],
        colour: RGB,
        width: float,
        alpha: float = 1.0,
        dash: tuple[float, float] | None = None,
        transform: Callable[[Array], Array] | None = None,
    ) -> None:
        """Draw the polylines ``lines`` in ``colour`` at opacity ``alpha``: :meth:`cover`, then :meth:`fill`."""
        self.cover(lines, width, dash, transform)
        self.fill(colour, alpha)

    def cover(
        self,
        lines: Sequence[Array],
        width: float,
        dash: tuple[float, float] | None = None,
        transform: Callable[[Array], Array] | None = None,
    ) -> None:
        """Mark the pixels the polylines ``lines`` (each ``(k, 2)`` pixel points, or points that
        ``transform`` maps to pixels, such as a :class:`WorldToPixels`; a single point is a dot)
        cover when drawn ``width`` pixels wide, ``dash`` = (on, off) pixels along each line or
        solid. Nothing shows until :meth:`fill`; where marked lines cross, a pixel keeps its
        strongest coverage."""
        lines = [line for line in lines if len(line)]
        if not lines:
            return
        x, y = _samples(lines, SAMPLE_SPACING * max(1.0, width / 2), dash, transform)
        keep = (x >= 0) & (x < self.width) & (y >= 0) & (y < self.height)
        if not np.any(keep):
            return
        # Eighths of a pixel: the pixel (>> 3) and where in it the sample falls (& 7).
        qx, qy = (x[keep] * SUBPIXEL).astype(np.intp), (y[keep] * SUBPIXEL).astype(np.intp)
        column, row = qx >> SHIFT, qy >> SHIFT
        offsets, coverage = _stamp(float(width), self.width + 2 * PAD)
        flat = (row + PAD) * (self.width + 2 * PAD) + (column + PAD)
        indices = flat[:, None] + offsets[None, :]
        np.maximum.at(
            self._coverage, indices.ravel(), coverage[(qy & (SUBPIXEL - 1)) * SUBPIXEL + (qx & (SUBPIXEL - 1))].ravel()
        )
        left, top, right, bottom = self._marked
        self._marked = (
            min(left, int(column.min())),
            min(top, int(row.min())),
            max(right, int(column.max())),
            max(bottom, int(row.max())),
        )

    def fill(self, colour: RGB, alpha: float = 1.0) -> None:
        """Mix ``colour`` at opacity ``alpha`` into the pixels :meth:`cover` marked, as much as each
        is covered, and clear the marks."""
        left, top, right, bottom = self._marked
        if top > bottom:
            return
        self._marked = NOTHING_MARKED
        # The marks lie within a stamp's reach (at most PAD) of the samples' pixels.
        layer = self._coverage.reshape(self.height + 2 * PAD, self.width + 2 * PAD)
        window = layer[top : bottom + 2 * PAD + 1, left : right + 2 * PAD + 1]
        marked = np.flatnonzero(window > 0)  # a boolean test: the fastest search
        rows, columns = np.divmod(marked, window.shape[1])
        amount = window[rows, columns] * np.float32(alpha)
        window[rows, columns] = 0.0
        rows, columns = rows + (top - PAD), columns + (left - PAD)
        inside = (rows >= 0) & (rows < self.height) & (columns >= 0) & (columns < self.width)
        self.mix(rows[inside] * self.width + columns[inside], colour, amount[inside])

    def mix(self, pixels: npt.NDArray[np.intp], colour: RGB, amount: npt.NDArray[np.float32] | float) -> None:
        """Move the flat-indexed ``pixels`` towards ``colour`` by ``amount`` (0 to 1 each)."""
        old = self._pixels[pixels].astype(np.float32)
        weight = np.reshape(amount, (-1, 1)) if np.ndim(amount) else np.float32(amount)
        self._pixels[pixels] = (old + (np.asarray(colour, dtype=np.float32) - old) * weight + 0.5).astype(np.uint8)

    def hlines(self, rows: Sequence[int], left: int, right: int, colour: RGB, alpha: float = 1.0) -> None:
        """One-pixel lines along ``rows``, columns ``left`` to ``right`` (inclusive), ``colour`` at ``alpha``."""
        self._paint((np.asarray(rows, dtype=np.intp), slice(max(left, 0), max(right + 1, 0))), colour, alpha)

    def vlines(self, columns: Sequence[int], top: int, bottom: int, colour: RGB, alpha: float = 1.0) -> None:
        """One-pixel lines down ``columns``, rows ``top`` to ``bottom`` (inclusive), ``colour`` at ``alpha``."""
        self._paint((slice(max(top, 0), max(bottom + 1, 0)), np.asarray(columns, dtype=np.intp)), colour, alpha)

    def _paint(self, where: tuple[slice | npt.NDArray[np.intp], ...], colour: RGB, alpha: float) -> None:
        old = self.image[where].astype(np.float32)
        self.image[where] = (old + (np.asarray(colour, dtype=np.float32) - old) * np.float32(alpha) + 0.5).astype(
            np.uint8
        )

    def text(
        self, text: str, column: float, row: float, colour: RGB, align: str = "left", upright: bool = True
    ) -> None:
        """One line of ``text`` in the built-in font, standing on pixel ``row``, starting (``align="left"``),
        centred (``"centre"``) or ending (``"right"``) at ``column``; ``upright=False`` turns it a
        quarter left, reading upwards (an axis label), centred at ``(column, row)``. What falls
        outside the image is cut off."""
        mask = text_mask(text)
        if upright:
            top = round(row) - BASELINE
            left = round(column - mask.shape[1] * {"left": 0.0, "centre": 0.5, "right": 1.0}[align])
        else:
            mask = np.rot90(mask)
            top, left = round(row - mask.shape[0] / 2), round(column - mask.shape[1] / 2)
        cut = mask[max(-top, 0) : max(self.height - top, 0), max(-left, 0) : max(self.width - left, 0)]
        top, left = max(top, 0), max(left, 0)
        self.image[top : top + cut.shape[0], left : left + cut.shape[1]][cut] = colour


def _samples(
    lines: list[Array],
    spacing: float,
    dash: tuple[float, float] | None,
    transform: Callable[[Array], Array] | None,
) -> tuple[Array, Array]:
    """Columns and rows of points ``spacing`` pixels apart or closer along each polyline of ``lines``
    (``(k, 2)`` each, ``k >= 1``, mapped to pixels by ``transform``; a single point is kept as it
    is), its vertices included, those in the gaps of ``dash`` left out: the pattern starts afresh
    on every line."""
    lines = [line if len(line) > 1 else np.repeat(line, 2, axis=0) for line in lines]
    sizes = np.array([len(line) for line in lines])
    points = np.concatenate(lines)
    if transform is not None:
        points = transform(points)
    joined = np.ones(len(points) - 1, dtype=bool)
    joined[np.cumsum(sizes)[:-1] - 1] = False
    x0, y0 = points[:-1, 0][joined], points[:-1, 1][joined]
    dx, dy = np.diff(points[:, 0])[joined], np.diff(points[:, 1])[joined]
    length = np.hypot(dx, dy)
    count = (length * (1 / spacing)).astype(np.intp) + 2
    segment = np.repeat(np.arange(len(x0)), count)
    t = (np.arange(len(segment)) - (np.cumsum(count) - count)[segment]) / (count - 1)[segment]
    x, y = x0[segment] + t * dx[segment], y0[segment] + t * dy[segment]
    if dash is None:
        return x, y
    # Arc length [px] at each segment's start, from its line's first vertex.
    travelled = np.cumsum(length) - length
    first = np.cumsum(sizes - 1) - (sizes - 1)
    along = travelled - travelled[first][np.repeat(np.arange(len(sizes)), sizes - 1)]
    on = (along[segment] + t * length[segment]) % (dash[0] + dash[1]) < dash[0]
    return x[on], y[on]
