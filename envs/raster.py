"""A small anti-aliased rasterizer in numpy: the envs' ``rgb_array`` frames are drawn with it.

A :class:`Raster` is a white ``(height, width, 3)`` uint8 image drawn on in pixel coordinates
``(column, row)`` (the pixel ``(c, r)`` covers ``[c, c + 1) x [r, r + 1)``; rows grow downwards);
a :class:`WorldToPixels` maps a box of the plane [m] onto a rectangle of it with equal scales on
both axes. A line segment is drawn a pixel at a time along its major axis (the one it runs
farther along): at each pixel centre on that axis, a short run of pixels across it is covered by
``clip(w / 2 + 1 / 2 - d, 0, 1)``, with ``d`` [px] the distance of the pixel's centre from the
segment and ``w`` [px] the stroke's width (butt ends, as matplotlib's). A pixel keeps the
strongest coverage any segment gives it, and takes that much of the stroke's colour.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ilc_steering.envs.glyphs import BASELINE, GLYPH_HEIGHT, text_pixels
from ilc_steering.errors import BadInput

__all__ = ["RGB", "Layer", "Pen", "Raster", "WorldToPixels"]

Array = npt.NDArray[np.float64]
RGB = tuple[int, int, int]

PAD = 8
"""Rows of the coverage layer above and below the image: the widest stroke's reach. Across a steep
segment, along a row, a stroke is kept only where the whole run fits in the row: a stroke within
its reach of the image's left or right edge is cut there."""


@dataclass(frozen=True)
class Pen:
    """How a line is drawn: ``width`` [px], and ``dash``, the (on, off) pixels along it, or solid."""

    width: float
    dash: tuple[float, float] | None = None


@dataclass(frozen=True)
class Layer:
    """Polylines ``lines`` (``(k, 2)`` each; a line of one point draws nothing) drawn with ``pen``
    (one for all, or one per line) in ``colour`` at opacity ``alpha``. Where its lines cross, a
    pixel keeps the strongest coverage they give it and takes the colour once."""

    lines: Sequence[Array]
    pen: Pen | Sequence[Pen]
    colour: RGB
    alpha: float = 1.0


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
        pixels: Array = np.asarray(points, dtype=np.float64) * self._factor + self._origin
        return pixels


class Raster:
    """A white ``(height, width, 3)`` uint8 image, drawn on in pixel coordinates."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.image = np.full((height, width, 3), 255, dtype=np.uint8)
        self._channels = [self.image.reshape(-1, 3)[:, c] for c in range(3)]
        # Coverage in 255ths, the output's own resolution, under marking: a quarter of float32's memory.
        self._coverage = np.zeros((height + 2 * PAD) * width, dtype=np.uint8)

    def stroke(
        self,
        lines: Sequence[Array],
        colour: RGB,
        pen: Pen | Sequence[Pen],
        alpha: float = 1.0,
        transform: Callable[[Array], Array] | None = None,
    ) -> None:
        """Draw the polylines ``lines`` with ``pen`` in ``colour`` at opacity ``alpha``: one :class:`Layer`."""
        self.draw([Layer(lines, pen, colour, alpha)], transform)

    def draw(self, layers: Sequence[Layer], transform: Callable[[Array], Array] | None = None) -> None:
        """Draw the ``layers`` in order, their lines in pixels or in what ``transform`` (such as a
        :class:`WorldToPixels`) maps to pixels. The segments of all layers are laid out at once:
        their pixel runs come out in the layers' order."""
        lines, pens, owners = [], [], []
        for k, layer in enumerate(layers):
            drawn = [layer.pen] * len(layer.lines) if isinstance(layer.pen, Pen) else list(layer.pen)
            if len(drawn) != len(layer.lines):
                raise BadInput(f"one pen for all lines or one per line: {len(drawn)} pens for {len(layer.lines)} lines")
            kept = [(line, pen) for line, pen in zip(layer.lines, drawn) if len(line) > 1]
            lines += [line for line, _ in kept]
            pens += [pen for _, pen in kept]
            owners += [k] * len(kept)
        if not lines:
            return
        # Across the major axis, a stroke reaches its half width (and half a pixel) over cos(45 deg) at most.
        reach = int(np.ceil((max(pen.width for pen in pens) / 2 + 0.5) * np.sqrt(2.0)))
        if reach > PAD:
            raise BadInput(f"a stroke is at most {2 * PAD / np.sqrt(2.0) - 1:.0f} pixels wide")
        runs = _runs(lines, [pen.dash for pen in pens], transform, (self.width, self.height))
        along, across, steep, stretch, line = runs
        # A run across a steep segment lies along a row: kept whole within the row, a reach from its ends.
        across = np.clip(across, -1.0, max(self.width, self.height))  # no overflow below; outside stays out
        base = np.floor(across).astype(np.intp)
        inside = (base >= np.where(steep, reach, 0)) & (base < np.where(steep, self.width - reach, self.height))
        along, base, line = along[inside], base[inside], line[inside]
        across, stretch, steep = across[inside], stretch[inside], steep[inside]
        # Distance [px] from the segment of the pixel centres across it, within reach, and their coverage.
        # In 255ths: 255 (w / 2 + 1 / 2 - d), clipped, with d = |offset - where the segment crosses| / stretch.
        offsets = np.arange(-reach, reach + 1)
        levels = (offsets + 0.5).astype(np.float32)[None, :] - (across - base).astype(np.float32)[:, None]
        np.abs(levels, out=levels)
        levels *= (255 / stretch).astype(np.float32)[:, None]
        edge = np.array([255 * (pen.width / 2 + 0.5) + 0.5 for pen in pens], dtype=np.float32)[line]
        np.subtract(edge[:, None], levels, out=levels)
        np.clip(levels, 0, 255, out=levels)
        stride = self.width
        flat = np.where(steep, along * stride + base, base * stride + along) + PAD * stride
        cells = flat[:, None] + np.where(steep, 1, stride)[:, None] * offsets[None, :]
        bounds = np.searchsorted(np.asarray(owners)[line], np.arange(len(layers) + 1))
        for k, layer in enumerate(layers):
            part = slice(bounds[k], bounds[k + 1])
            if part.start == part.stop:
                continue
            np.maximum.at(self._coverage, cells[part].ravel(), levels[part].astype(np.uint8).ravel())
            self._fill(int(flat[part].min()) // stride - PAD, int(flat[part].max()) // stride - PAD, layer)

    def dots(
        self,
        centres: Array,
        diameter: float,
        colour: RGB,
        alpha: float = 1.0,
        transform: Callable[[Array], Array] | None = None,
    ) -> None:
        """Discs of ``diameter`` pixels at ``centres`` ``(k, 2)`` (pixels, or mapped to pixels by
        ``transform``) in ``colour`` at opacity ``alpha``, one layer."""
        reach = int(np.ceil(diameter / 2 + 1.0))
        if reach > PAD:
            raise BadInput(f"a dot is at most {2 * PAD - 2} pixels across, got {diameter}")
        points = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
        if transform is not None:
            points = transform(points)
        points = points[
            (points[:, 0] >= reach)
            & (points[:, 0] < self.width - reach)
            & (points[:, 1] >= 0)
            & (points[:, 1] < self.height)
        ]
        if not len(points):
            return
        base = np.floor(points).astype(np.intp)
        dr, dc = (a.ravel() for a in np.mgrid[-reach : reach + 1, -reach : reach + 1])
        distance = np.hypot(base[:, 1:] + dr + 0.5 - points[:, 1:], base[:, :1] + dc + 0.5 - points[:, :1])
        stride = self.width
        flat = (base[:, 1:] + PAD) * stride + base[:, :1] + (dr * stride + dc)
        np.maximum.at(self._coverage, flat.ravel(), _levels(diameter / 2 + 0.5 - distance).ravel())
        self._fill(int(base[:, 1].min()), int(base[:, 1].max()), Layer([], [], colour, alpha))

    def _fill(self, top: int, bottom: int, layer: Layer) -> None:
        """Mix the layer's colour at its opacity into the pixels the coverage marks, as much as each is
        covered, and clear the marks: they lie within PAD rows of the image's rows ``top`` to ``bottom``, a band
        of whole rows of the coverage, contiguous, where a boolean test finds them fastest."""
        band = self._coverage[top * self.width : (bottom + 2 * PAD + 1) * self.width]
        marked = np.flatnonzero(band > 0)
        amount = band[marked] * np.float32(layer.alpha / 255)
        band[marked] = 0
        pixels = marked + (top - PAD) * self.width  # the layer's rows are the image's, PAD lower
        inside = (pixels >= 0) & (pixels < self.height * self.width)
        self.mix(pixels[inside], layer.colour, amount[inside])

    def mix(self, pixels: npt.NDArray[np.intp], colour: RGB, amount: npt.NDArray[np.float32] | float) -> None:
        """Move the flat-indexed ``pixels`` towards ``colour`` by ``amount`` (0 to 1 each)."""
        weight = np.asarray(amount, dtype=np.float32)
        for channel, value in zip(self._channels, colour):  # one plane at a time: 1-d gathers are the fast ones
            old = channel[pixels].astype(np.float32)
            channel[pixels] = (old + (np.float32(value) - old) * weight + np.float32(0.5)).astype(np.uint8)

    def hlines(self, rows: Sequence[int], left: int, right: int, colour: RGB) -> None:
        """Opaque one-pixel lines along ``rows``, columns ``left`` to ``right`` (inclusive)."""
        rows = [r for r in rows if 0 <= r < self.height]
        self.image[rows, max(left, 0) : max(right + 1, 0)] = colour

    def vlines(self, columns: Sequence[int], top: int, bottom: int, colour: RGB) -> None:
        """Opaque one-pixel lines down ``columns``, rows ``top`` to ``bottom`` (inclusive)."""
        columns = [c for c in columns if 0 <= c < self.width]
        self.image[max(top, 0) : max(bottom + 1, 0), columns] = colour

    def text(
        self, text: str, column: float, row: float, colour: RGB, align: str = "left", upright: bool = True
    ) -> None:
        """One line of ``text`` in the built-in font, standing on pixel ``row``, starting (``align="left"``),
        centred (``"centre"``) or ending (``"right"``) at ``column``; ``upright=False`` turns it a
        quarter left, reading upwards (an axis label), centred at ``(column, row)``. What falls
        outside the image is cut off."""
        rows, columns, width = text_pixels(text)
        if upright:
            top = round(row) - BASELINE
            left = round(column - width * {"left": 0.0, "centre": 0.5, "right": 1.0}[align])
        else:
            rows, columns = width - 1 - columns, rows
            top, left = round(row - width / 2), round(column - GLYPH_HEIGHT / 2)
        height, across = (GLYPH_HEIGHT, width) if upright else (width, GLYPH_HEIGHT)
        rows, columns = rows + top, columns + left
        if top < 0 or left < 0 or top + height > self.height or left + across > self.width:
            inside = (rows >= 0) & (rows < self.height) & (columns >= 0) & (columns < self.width)
            rows, columns = rows[inside], columns[inside]
        self.image[rows, columns] = colour


def _levels(coverage: npt.NDArray[np.floating]) -> npt.NDArray[np.uint8]:
    """Coverage (clipped to 0 to 1) in 255ths."""
    levels: npt.NDArray[np.uint8] = (np.clip(coverage, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)
    return levels


def _runs(
    lines: list[Array],
    dashes: list[tuple[float, float] | None],
    transform: Callable[[Array], Array] | None,
    size: tuple[int, int],
) -> tuple[npt.NDArray[np.intp], Array, npt.NDArray[np.bool_], Array, npt.NDArray[np.intp]]:
    """The pixel centres along the major axis of every segment of ``lines`` (``(k, 2)`` each, ``k >= 2``,
    mapped to pixels by ``transform``) within an image of ``size`` (width, height) [px], those in the
    gaps of each line's dash (on, off) [px] left out (the pattern starts afresh on every line): each
    centre's pixel index along that axis; where the segment crosses it on the other axis [px];
    whether the segment is steep (runs farther along the rows' axis, y); the segment's length per
    pixel of its major axis, ``sqrt(1 + slope**2)``; and the index of its line. A segment with a
    coordinate that is not finite has none."""
    sizes = np.array([len(line) for line in lines])
    points = np.concatenate(lines)
    if transform is not None:
        points = transform(points)
    owner = np.repeat(np.arange(len(lines)), sizes - 1)
    joined = np.ones(len(points) - 1, dtype=bool)
    joined[np.cumsum(sizes)[:-1] - 1] = False
    finite = np.isfinite(points[:, 0]) & np.isfinite(points[:, 1])
    drawn = joined & finite[:-1] & finite[1:]
    delta = np.subtract(points[1:], points[:-1], out=np.zeros_like(points[1:]), where=drawn[:, None])
    start, delta = points[:-1][joined], delta[joined]
    steep = np.abs(delta[:, 1]) > np.abs(delta[:, 0])
    major, minor = steep.astype(np.intp), 1 - steep.astype(np.intp)
    index = np.arange(len(start))
    a0, b0, da, db = start[index, major], start[index, minor], delta[index, major], delta[index, minor]
    # Pixel centres on the major axis within the segment and the image; none for a segment not finite.
    finite = drawn[joined]
    low = np.where(finite, np.maximum(np.minimum(a0, a0 + da), 0.0), 0.0)
    high = np.where(finite, np.minimum(np.maximum(a0, a0 + da), np.where(steep, size[1], size[0])), -1.0)
    first = np.ceil(low - 0.5)
    count = np.maximum(np.floor(high - 0.5) - first + 1, 0).astype(np.intp)
    first = first.astype(np.intp)
    segment = np.repeat(index, count)
    centre = first[segment] + (np.arange(len(segment)) - (np.cumsum(count) - count)[segment]) + 0.5
    slope = db / np.where(da == 0, 1.0, da)
    across = b0[segment] + (centre - a0[segment]) * slope[segment]
    stretch = np.sqrt(1.0 + slope * slope)[segment]
    dashed = np.flatnonzero(np.array([dash is not None for dash in dashes])[owner][segment])
    if len(dashed):  # the runs of dashed lines in their gaps are left out
        length = np.hypot(delta[:, 0], delta[:, 1])
        travelled = np.cumsum(length) - length
        from_line_start = travelled - travelled[np.cumsum(sizes - 1) - (sizes - 1)][owner]
        pattern = np.array([dash or (0.0, 0.0) for dash in dashes])[owner[segment[dashed]]]
        which = segment[dashed]
        s = from_line_start[which] + np.abs(centre[dashed] - a0[which]) * stretch[dashed]
        keep = np.ones(len(segment), dtype=bool)
        keep[dashed[s % pattern.sum(axis=1) >= pattern[:, 0]]] = False
        centre, across, stretch, segment = centre[keep], across[keep], stretch[keep], segment[keep]
    return (centre - 0.5).astype(np.intp), across, steep[segment], stretch, owner[segment]
