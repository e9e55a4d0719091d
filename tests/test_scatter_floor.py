"""Issue 48's Done-when on the MuJoCo car's scattering config, as ``benchmarks/mujoco_car.py``'s
floor table measures it: ``robust_ilc`` and ``newton_ilc`` reach and hold (the last five of 15
trials) four times the measured scatter, their final stretch inside beginning by trial 6."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco", reason='the [mujoco] extra: pip install "ilc-steering[mujoco]"')

from ilc_steering.config import load_config
from ilc_steering.envs.scenario import Scenario
from ilc_steering.runner import run_ilc

SCATTER = Path(__file__).resolve().parents[1] / "configs" / "mujoco_forward_parking_scatter.yaml"


@pytest.fixture(scope="module")
def tolerance() -> tuple[float, float]:
    """Four times the std of 20 repeats of the nominal solution (x and y pooled; theta), the
    benchmark's floor tolerance (6.47 mm / 3.76 mrad when measured)."""
    scenario = Scenario.from_config(load_config(SCATTER))
    c = np.repeat(scenario.nominal.solve()[None], 20, axis=0)
    scenario.run(c[:1])  # the plant settles on its tyres once, as the benchmark's
    std = scenario.to_world(scenario.run(c).final).std(axis=0)
    return 4.0 * float(np.hypot(std[0], std[1]) / np.sqrt(2)), 4.0 * float(std[2])


@pytest.mark.slow  # 10 runs of 15 MuJoCo trials, about 25 s of CPU
@pytest.mark.parametrize("learner", ["robust_ilc", "newton_ilc"])
def test_the_learners_hold_four_times_the_scatter_from_trial_six(learner, tolerance) -> None:
    """Env seeds 1-5 (the benchmark's). Before the band counted the trials before its entry, seeds
    2 and 5 relapsed at trials 6-7 for both learners: the band's first mean was one draw, chased whole.
    The margins are thin (the worst of trials 6-15: 0.98 of the tolerance for robust_ilc's seed 1,
    0.99 for newton_ilc's seed 5): a change of the learners' steps may move a run across it."""
    cartesian, orientation = tolerance
    loaded = load_config(SCATTER)
    config = replace(
        loaded,
        learning=replace(
            loaded.learning,
            tolerance=replace(loaded.learning.tolerance, cartesian=cartesian, orientation=orientation),
        ),
    )
    for seed in range(1, 6):
        result = run_ilc(config, 15, learner=learner, seed=seed)
        verdict = result.verdict
        inside = [
            not r.left_chart and (r.cartesian_error or 0.0) <= cartesian and (r.orientation_error or 0.0) <= orientation
            for r in result.trials
        ]
        assert verdict.converged_at is not None and verdict.converged_at <= 6, (seed, inside)
        assert verdict.held >= 5 and all(inside[5:]), (seed, inside)
