"""The comparison figures tell methods apart: a colour per family, a (colour, marker) per method, however
many, and the legend outside the panels."""

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_hex

from ilc_steering.agents import registry
from ilc_steering.compare import command as compare
from ilc_steering.compare.figures import scenario_figure
from ilc_steering.figure_styles import FAMILY_COLOURS, MARKERS, method_styles


def cells(methods, priors=("nominal", "none"), seeds=(0, 1, 2)):
    """Cells of every method: ILC-like curves that fall at a rate of their own, on one scenario."""
    out = []
    for prior in priors:
        for k, method in enumerate(methods):
            for seed in seeds:
                trials = 20 + 15 * k
                errors = 0.1 * np.exp(-(0.2 + 0.02 * k + 0.01 * seed) * np.arange(trials))
                curve = [[t + 1, float(e)] for t, e in enumerate(errors)]
                out.append(
                    {"prior": prior, "method": method, "scenario": "s", "seed": seed, "trials": trials, "curve": curve}
                )
    return out


def drawn(figure):
    """Each axes' method curves as {label: (colour, marker, linestyle)}, after a draw."""
    FigureCanvasAgg(figure).draw()
    return [
        {
            line.get_label(): (to_hex(line.get_color()), line.get_marker(), line.get_linestyle())
            for line in ax.get_lines()
            if not line.get_label().startswith("_")
        }
        for ax in figure.axes
    ]


@pytest.fixture
def grown(monkeypatch):
    """The registry as others will grow it: a method added to each family joins it."""
    table = dict(registry.REGISTRY)
    for method, family in (("droq", "RL"), ("extra_blackbox", "black-box"), ("extra_model", "model-based")):
        table[method] = registry.LearnerSpec(method, family, "pkg.mod:make", "model_trials")
    monkeypatch.setattr(registry, "REGISTRY", table)
    return [*registry.ids(), "my_learners:make", "mypkg.mod:make"]


def test_every_method_of_a_figure_has_its_own_colour_and_marker_and_its_familys_colour(grown):
    figure = scenario_figure(cells(grown), "s", compare.method_families(grown))
    panels = drawn(figure)
    assert len(panels) == 2
    for styles in panels:
        assert sorted(styles) == sorted(grown)  # every method drawn in every panel
        pairs = [(colour, marker) for colour, marker, _ in styles.values()]
        assert len(set(pairs)) == len(pairs)
        families = {
            "model-based": registry.ids("model-based"),
            "black-box": registry.ids("black-box"),
            "RL": registry.ids("RL"),
            "yours": ("my_learners:make", "mypkg.mod:make"),
        }
        colours = {family: {styles[m][0] for m in methods} for family, methods in families.items()}
        assert all(len(c) == 1 for c in colours.values()), colours  # one colour per family, the added methods too
        assert len(set().union(*colours.values())) == len(families)  # and each family its own
        assert colours["model-based"] == {FAMILY_COLOURS[0]} and colours["yours"] == {"#000000"}
        for methods in families.values():  # within a family, marker and line style tell the members apart
            assert len({styles[m][1:] for m in methods}) == len(methods)


def test_the_legend_lies_outside_every_panel_and_inside_the_figure(grown):
    figure = scenario_figure(cells(grown), "s", compare.method_families(grown))
    drawn(figure)
    (legend,) = figure.legends
    box = legend.get_window_extent()
    for ax in figure.axes:
        assert not box.overlaps(ax.get_window_extent()), (box, ax.get_window_extent())
    canvas = figure.bbox
    assert canvas.x0 <= box.x0 and box.x1 <= canvas.x1 and canvas.y0 <= box.y0 and box.y1 <= canvas.y1
    assert figure.get_suptitle() and not box.overlaps(figure._suptitle.get_window_extent())
    labels = [text.get_text() for text in legend.get_texts()]
    model_based = registry.ids("model-based")
    assert labels[: 1 + len(model_based)] == ["model-based:", *model_based]  # grouped by family
    assert labels.count("yours:") == 1 and set(grown) <= set(labels)


def test_styles_stay_distinct_for_any_count_of_methods_and_families():
    families = {
        f"family {i}": tuple(f"m{i}.{j}" for j in range(3 * len(MARKERS))) for i in range(len(FAMILY_COLOURS) + 3)
    }
    methods = [m for members in families.values() for m in members] + ["unlisted", "x:y"]
    styles = method_styles(methods, families)
    pairs = [(s.colour, s.marker) for s in styles.values()]
    assert len(set(pairs)) == len(pairs) == len(methods)
    assert styles["unlisted"].family == styles["x:y"].family == "other"
    first = styles["m0.0"]
    assert first.colour == FAMILY_COLOURS[0] and styles[f"m0.{len(MARKERS)}"].marker == first.marker
    assert styles[f"m0.{len(MARKERS)}"].colour != first.colour  # a second round of markers: a lighter shade


def test_a_figure_of_many_methods_keeps_its_legend_in_the_figure():
    families = {"RL": tuple(f"rl{i}" for i in range(40))}
    figure = scenario_figure(cells(list(families["RL"]), priors=("nominal",), seeds=(0,)), "s", families)
    drawn(figure)
    box, canvas = figure.legends[0].get_window_extent(), figure.bbox
    assert box.y0 >= canvas.y0 and box.x1 <= canvas.x1  # two columns, not a legend running off the page
    assert not box.overlaps(figure.axes[0].get_window_extent())
