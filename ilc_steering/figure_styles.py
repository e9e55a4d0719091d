"""Line styles that tell many methods apart: a colour per family of methods, markers and line styles within it.

A figure of the comparison draws a dozen methods and more. Ten colours cannot tell them apart,
and the reader asks first which *kind* of method a curve is; so the colour says the family
(model-based, black-box, RL, yours, in :data:`FAMILY_COLOURS` by the family's place), and the
marker and the line style say the member. Past :data:`MARKERS` members of one family, the colour
is lightened by a step per round of markers (and a family past the palette's end by as many as it
takes), so no two methods of a figure share a colour and a marker: up to hundreds of methods, as
many as 8-bit shades of a colour hold. Pure Python: nothing here imports matplotlib.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

__all__ = ["FAMILY_COLOURS", "LINESTYLES", "MARKERS", "Style", "method_styles"]

FAMILY_COLOURS = (
    "#1f77b4",  # blue: model-based
    "#ff7f0e",  # orange: black-box
    "#d62728",  # red: RL
    "#000000",  # black: yours
    "#9467bd",  # purple, and on: families beyond these
    "#2ca02c",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
)
"""The colour of each family, by its place among the families; a method in no family is drawn in
the colour after the last family's."""
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">", "h", "p")
"""The members of a family, in order."""
LINESTYLES = ("-", "--", "-.", ":")
"""The members of a family, in order: with the marker, a curve that hides another is still told apart."""
LIGHTEN = 0.25
"""Each further shade of a family's colour (its members past a round of markers) moves this much
of the rest of the way to white."""


@dataclass(frozen=True)
class Style:
    """How one method is drawn: its family, colour (hex), marker and line style (matplotlib's names)."""

    family: str
    colour: str
    marker: str
    linestyle: str


def _lighten(colour: str, amount: float) -> str:
    """``colour`` (``#rrggbb``) moved ``amount`` of the way to white."""
    channels = [int(colour[i : i + 2], 16) for i in (1, 3, 5)]
    return "#" + "".join(f"{round(c + amount * (255 - c)):02x}" for c in channels)


def method_styles(
    methods: Sequence[str], families: Mapping[str, Sequence[str]], other: str = "other"
) -> dict[str, Style]:
    """The style of each of ``methods``: the colour of its family (the first of ``families``
    listing it; ``other`` for a method none lists), and the marker and line style of its place
    among the family's members in ``methods``. No two methods share a colour and a marker."""
    names = [*families, other]
    family_of = {m: next((f for f, members in families.items() if m in members), other) for m in methods}
    styles: dict[str, Style] = {}
    count: dict[str, int] = {}
    for method in methods:
        family = family_of[method]
        index = count.get(family, 0)
        count[family] = index + 1
        place = names.index(family)
        base = FAMILY_COLOURS[place % len(FAMILY_COLOURS)]
        marker = MARKERS[index % len(MARKERS)]
        shade = index // len(MARKERS)  # another round of markers: a lighter shade
        taken = {(s.colour, s.marker) for s in styles.values()}
        while (colour := _lighten(base, 1 - (1 - LIGHTEN) ** shade)) != "#ffffff" and (colour, marker) in taken:
            shade += 1  # a family past the palette's end shares a colour with an earlier one: shade it apart
        styles[method] = Style(family, colour, marker, LINESTYLES[index % len(LINESTYLES)])
    return styles
