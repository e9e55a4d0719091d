"""Issue 48's measured Done-whens: benchmarks/noisy.py (100 seeded runs of a noisy in-family plant:
its plant and tolerance, its summary, docs/noisy.md quoting the committed artifact) and the MuJoCo
scatter config's floor table in docs/mujoco.md."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
_SPEC = importlib.util.spec_from_file_location("noisy_benchmark", ROOT / "benchmarks/noisy.py")
assert _SPEC is not None and _SPEC.loader is not None
noisy = importlib.util.module_from_spec(_SPEC)  # a script of benchmarks/, not a package
sys.modules[_SPEC.name] = noisy  # dataclasses look their module up by name
_SPEC.loader.exec_module(noisy)
_CAR = importlib.util.spec_from_file_location("mujoco_car_benchmark", ROOT / "benchmarks/mujoco_car.py")
assert _CAR is not None and _CAR.loader is not None
mujoco_car = importlib.util.module_from_spec(_CAR)
sys.modules[_CAR.name] = mujoco_car
_CAR.loader.exec_module(mujoco_car)


def test_the_plant_is_forward_parking_with_the_noise_and_a_tolerance_of_four_sigma() -> None:
    config = noisy.noisy_config("forward_parking", 2e-3, 4.0, 15)
    assert config.simulation.measurement_noise == (2e-3,) * 4
    assert config.learning.tolerance.cartesian == config.learning.tolerance.orientation == pytest.approx(8e-3)
    assert config.learning.trials == 15
    assert config.plant.true_wheelbase == pytest.approx(1.1 * config.plant.wheelbase)  # in the model family


def test_the_summary_counts_holds_and_ratios() -> None:
    def run(seed: int, holds: bool, cartesian: float, orientation: float) -> dict[str, object]:
        return {
            "learner": "x",
            "seed": seed,
            "holds_last": holds,
            "converged_at": 2 if holds else None,
            "scatter_cartesian": cartesian,
            "scatter_orientation": orientation,
            "worst_last_m": 1e-3 * seed,
            "worst_last_rad": 2e-3,
            "seconds": 1.0,
        }

    runs = [run(1, True, 1.0, 0.5), run(2, True, 1.4, 1.2), run(3, False, math.nan, math.nan), run(4, True, 2.0, 1.0)]
    row = noisy.summarize(runs, "x")
    assert row["hold_share"] == 0.75 and row["converged_share"] == 0.75 and row["estimated"] == 3
    assert row["within_1_5"] == 4 / 8  # NaN (no estimate) is not within
    assert row["runs_within_1_5"] == 1 / 4
    assert (row["cartesian_median"], row["cartesian_min"], row["cartesian_max"]) == (1.4, 1.0, 2.0)
    assert row["worst_last_m"] == pytest.approx(4e-3)


def test_the_page_quotes_its_artifact_and_the_done_when_holds() -> None:
    page = (ROOT / "docs/noisy.md").read_text()
    assert (ROOT / "results/noisy/noisy.md").read_text().strip() in page
    rows = {r["learner"]: r for r in json.loads((ROOT / "results/noisy/noisy.json").read_text())["rows"]}
    assert set(rows) == {"robust_ilc", "newton_ilc", "ilc_paper"}
    for name in ("robust_ilc", "newton_ilc"):
        row = rows[name]
        assert row["runs"] == 100 and row["hold_share"] >= 0.95  # the last five trials hold 4 sigma
        assert 1 / 1.5 <= row["cartesian_median"] <= 1.5 and 1 / 1.5 <= row["orientation_median"] <= 1.5
    runs = json.loads((ROOT / "results/noisy/noisy_runs.json").read_text())["rows"]
    below = [sum(r["below_floor"] for r in runs if r["learner"] == name) for name in rows]
    relapsed = [sum(r["relapses"] > 0 for r in runs if r["learner"] == name) for name in rows]
    assert f"In {below[0]}, {below[1]} and {below[2]} runs" in " ".join(page.split())
    assert f"in {relapsed[0]}, {relapsed[1]} and {relapsed[2]} runs of the hundred" in " ".join(page.split())


def test_the_floor_table_scores_a_run_by_both_readings() -> None:
    # inside at 2-3, out at 4, inside again from 5: the literal reading (inside by 6, last 5 inside) and the
    # strict one (the final stretch from 6 or before) agree; from 7 only the literal holds
    early = mujoco_car.stretches([False, True, True, False] + [True] * 11)
    assert early == {"first_inside": 2, "stretch_from": 5, "held": 11, "relapses": 1}
    assert mujoco_car.readings(early, 6, 5) == {"met_literal": True, "met_strict": True}
    late = mujoco_car.stretches([False, True, True, False, False, False] + [True] * 9)
    assert (late["stretch_from"], late["held"]) == (7, 9)
    assert mujoco_car.readings(late, 6, 5) == {"met_literal": True, "met_strict": False}
    ends_out = mujoco_car.stretches([True] * 14 + [False])
    assert ends_out == {"first_inside": 1, "stretch_from": None, "held": 0, "relapses": 1}
    assert mujoco_car.readings(ends_out, 6, 5) == {"met_literal": False, "met_strict": False}
    never = mujoco_car.stretches([False] * 15)
    assert mujoco_car.readings(never, 6, 5) == {"met_literal": False, "met_strict": False}


def test_the_pooled_std_is_the_rms_of_x_and_y() -> None:
    offsets = np.array([[1.0, 3.0, 0.5], [-1.0, -3.0, -0.5]])  # std 1 in x, 3 in y, 0.5 in theta
    assert mujoco_car.pooled_std(offsets) == pytest.approx([math.sqrt(5), 0.5])


def test_the_mujoco_page_quotes_its_floor_table() -> None:
    """benchmarks/mujoco_car.py's floor table (issue 48's Done-when on the scatter config), as written:
    the learners' and the oracle's runs on the same seeds, each scored by both readings."""
    page = (ROOT / "docs/mujoco.md").read_text()
    assert (ROOT / "results/mujoco/mujoco_floor.md").read_text().strip() in page
    floor = json.loads((ROOT / "results/mujoco/mujoco_floor.json").read_text())
    rows, within, last = floor["rows"], floor["within"], floor["last"]
    assert floor["repeats"] >= 200 and floor["cartesian_m"] == pytest.approx(4 * floor["scatter_m"])
    seeds = {name: [r["seed"] for r in rows if r["learner"] == name] for name in floor["summary"]}
    assert set(seeds) == {"robust_ilc", "newton_ilc", mujoco_car.ORACLE} and len(set(map(tuple, seeds.values()))) == 1
    for row in rows:
        assert {k: row[k] for k in ("met_literal", "met_strict")} == mujoco_car.readings(row, within, last)
    words = " ".join(page.split())
    for name, met in floor["summary"].items():
        for reading in ("literal", "strict"):
            assert met[reading] == sum(r[f"met_{reading}"] for r in rows if r["learner"] == name)
        named = "the oracle" if name == mujoco_car.ORACLE else f"`{name}`"
        runs = len(seeds[name])
        said = f"{named} meets the literal reading in {met['literal']} of {runs} runs"
        assert f"{said} and the strict one in {met['strict']} of {runs}" in words
