"""The trial loop: an ILC agent learning on a registered env, trial after trial."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym

from ilc_steering.agents.ilc import ILCAgent
from ilc_steering.config import SteeringConfig, ToleranceConfig, load_config

__all__ = ["RunResult", "TrialRecord", "run_ilc", "within_tolerance"]

ENV_ID = "ilc_steering/ChainedSteering-v0"


@dataclass(frozen=True)
class TrialRecord:
    """One trial: its errors, final configuration (world frame), chained error and action."""

    trial: int
    error_norm: float
    cartesian_error: float | None
    orientation_error: float | None
    final_state: list[float]
    error: list[float]
    action: list[float]

    def to_json(self) -> dict[str, Any]:
        record = asdict(self)
        return {k: v for k, v in record.items() if v is not None}


@dataclass(frozen=True)
class RunResult:
    name: str
    trials: list[TrialRecord]
    converged_at: int | None

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "trials": [t.to_json() for t in self.trials], "converged_at": self.converged_at}


def within_tolerance(tolerance: ToleranceConfig, info: dict[str, Any]) -> bool:
    """Whether a trial's ``info`` meets the tolerance: Cartesian and orientation for a car,
    the chained-error norm otherwise."""
    if tolerance.error is not None and info["error_norm"] > tolerance.error:
        return False
    if tolerance.cartesian is not None and info["cartesian_error"] > tolerance.cartesian:
        return False
    if tolerance.orientation is not None and info["orientation_error"] > tolerance.orientation:
        return False
    return True


def run_ilc(
    config: str | Path | SteeringConfig,
    trials: int | None = None,
    on_trial: Callable[[TrialRecord], None] | None = None,
) -> RunResult:
    """Run the ILC agent of eqs. 33-34 for ``trials`` trials (default: the config's).

    ``on_trial`` is called with each record as soon as the trial ends.
    """
    config = load_config(config)
    count = config.learning.trials if trials is None else trials
    if count < 1:
        raise ValueError(f"trials must be >= 1, got {count}")
    env = gym.make(ENV_ID, config=config)
    agent = ILCAgent(env.unwrapped.nominal_model, config.learning.nu_a, config.learning.nu_b)  # type: ignore[attr-defined]
    records: list[TrialRecord] = []
    converged_at = None
    for k in range(1, count + 1):
        observation, _ = env.reset(seed=k)
        _, _, _, _, info = env.step(agent.act(observation))
        agent.learn(info)
        record = TrialRecord(
            trial=k,
            error_norm=info["error_norm"],
            cartesian_error=info.get("cartesian_error"),
            orientation_error=info.get("orientation_error"),
            final_state=info["q_final"].tolist(),
            error=info["error"].tolist(),
            action=info["action"].tolist(),
        )
        records.append(record)
        if on_trial is not None:
            on_trial(record)
        if converged_at is None and within_tolerance(config.learning.tolerance, info):
            converged_at = k
    env.close()
    return RunResult(config.name, records, converged_at)
