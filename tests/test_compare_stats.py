"""How the comparison reports trials across seeds (issue 35): medians and interquartile means with
scipy's bootstrap intervals, the performance profile, the progress bar, the ablation's seeds and the
generated tables."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import bootstrap, trim_mean

from ilc_steering.compare import tables as compare_tables
from ilc_steering.compare.args import Args
from ilc_steering.compare.figures import profile
from ilc_steering.compare.plan import plan
from ilc_steering.compare.stats import BOOTSTRAP_RESAMPLES, statistic_ci
from ilc_steering.engine.runs import Progress

ROOT = Path(__file__).resolve().parent.parent


def test_the_interval_is_scipys_percentile_bootstrap_on_seeds_that_all_got_there() -> None:
    values = [3.0, 5.0, 4.0, 9.0, 2.0, 4.0, 6.0, 3.0, 7.0, 5.0]
    for name, function in (("median", np.median), ("iqm", lambda x, axis: trim_mean(x, 0.25, axis=axis))):
        value, interval = statistic_ci(values, name, seed=3)
        expected = bootstrap(
            (np.array(values),),
            (lambda x, axis: np.median(x, axis=axis)) if name == "median" else function,
            n_resamples=BOOTSTRAP_RESAMPLES,
            method="percentile",
            vectorized=True,
            rng=np.random.default_rng(3),
        ).confidence_interval
        assert interval == pytest.approx((expected.low, expected.high))
        assert interval is not None and interval[0] <= value <= interval[1]
    assert statistic_ci(values, "iqm")[0] == pytest.approx(trim_mean(values, 0.25))


def test_seeds_that_never_got_there_decide_a_statistic_only_where_they_enter_it() -> None:
    two_missing = [1000.0, 1200.0, 900.0, math.inf, 1100.0, 950.0, 1300.0, math.inf, 1050.0, 1150.0]
    median, (low, high) = statistic_ci(two_missing, "median")  # type: ignore[misc]
    assert math.isfinite(median) and math.isfinite(low) and math.isinf(high)
    iqm, _ = statistic_ci(two_missing, "iqm")
    assert iqm == pytest.approx(np.mean(sorted(two_missing)[2:8]))  # the top quarter cut, both inf in it
    six_missing = [10.0, 20.0, 30.0, 40.0, *[math.inf] * 6]
    assert math.isinf(statistic_ci(six_missing, "median")[0]) and math.isinf(statistic_ci(six_missing, "iqm")[0])
    assert statistic_ci([2.0] * 10, "median") == (2.0, (2.0, 2.0))
    assert statistic_ci([7.0], "iqm") == (7.0, None)


def test_the_performance_profile_is_the_share_of_runs_within_t_trials() -> None:
    cells = [{"trials_to": {"1cm": t}} for t in (1, 3, 3, None)]
    grid = np.array([1, 2, 3, 100])
    assert profile(cells, "1cm", grid).tolist() == [0.25, 0.25, 0.75, 0.75]


def test_the_progress_bar_counts_and_estimates_from_the_expected_costs() -> None:
    progress = Progress({"a": 10.0, "b": 10.0, "c": 20.0, "d": 0.0}, workers=2)
    first = progress.line("a")
    assert first.startswith("[######------------------] 1/4 (25%)") and "left" in first
    progress.line("c")
    progress.line("b")
    assert "4/4 (100%), about 0 s left" in progress.line("d")


def test_the_ablation_runs_the_first_seeds_only() -> None:
    the_plan = plan(Args(methods=("ilc",), scenarios=("forward_parking",), seeds=tuple(range(10)), ablation_seeds=3))
    seeds = {prior: [cell[3] for cell in the_plan.grid if cell[0] == prior] for prior in ("nominal", "none")}
    assert seeds == {"nominal": list(range(10)), "none": [0, 1, 2]}
    assert the_plan.settings["ablation_seeds"] == 3  # recorded: a resume with another count is refused
    with pytest.raises(ValueError, match="--ablation-seeds"):
        plan(Args(methods=("ilc",), scenarios=("forward_parking",), ablation_seeds=0))


def test_a_table_block_that_differs_from_the_run_is_found_and_rewritten(tmp_path: Path) -> None:
    tables = {"headline-1cm": "| a |\n| --- |\n| 1 |\n"}
    text = "intro\n<!-- compare-table: headline-1cm -->\nold\n<!-- /compare-table -->\nend\n"
    rendered = compare_tables.render(text, tables)
    assert (
        rendered == "intro\n<!-- compare-table: headline-1cm -->\n| a |\n| --- |\n| 1 |\n<!-- /compare-table -->\nend\n"
    )
    dotted = text.replace("headline-1cm", "headline-0.5mm")
    assert "| 1 |" in compare_tables.render(dotted, {"headline-0.5mm": tables["headline-1cm"]})
    with pytest.raises(ValueError, match="marker without"):
        compare_tables.render("<!-- compare-table: Bad Name -->\nx\n<!-- /compare-table -->", tables)
    with pytest.raises(ValueError, match="names 'nope'"):
        compare_tables.render("<!-- compare-table: nope -->\nx\n<!-- /compare-table -->", tables)


@pytest.mark.skipif(not (ROOT / "results" / "compare" / "compare.json").is_file(), reason="needs the source tree")
@pytest.mark.extra("rl")  # the committed RL cells' budgets are read from their hyperparameter files, checked on SB3
def test_the_readme_and_the_comparison_page_show_the_committed_runs_tables() -> None:
    files = [ROOT / "README.md", ROOT / "docs" / "comparison.md"]
    assert all(compare_tables.BLOCK.search(path.read_text()) for path in files)  # both hold generated tables
    assert compare_tables.check(ROOT / "results" / "compare", files) == []
