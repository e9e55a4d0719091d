"""Why the servo tasks failed ``robust_ilc`` before its family had the servo's parameters, in numbers.

    python benchmarks/robustness_diagnosis.py [--out DIR]

writes ``diagnosis.json`` (committed in ``results/robustness``; read by ``docs/diagnosis.md``).
On ``parallel_parking_servo``, after the first trial (the nominal solution) it fits the geometry's
family and the family with the steering offset and lag to that trial, as ``robust_ilc`` does, and
reports what each explains; then, on the identified model, how near the goal each solver of
``robust_ilc`` gets (Newton along the homotopy of the last round; Gauss-Newton's minimum-norm
steps); and the singular values of the model's Jacobian at the nominal solution. It also counts
the trailer map's lost cells (solvable, not converged) of the committed ``robust_ilc`` rows, and
each method's share of the solvable plants on the rows of the servo and lag maps computed so far.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.agents.levenberg_marquardt import levenberg_marquardt
from ilc_steering.agents.solver import gauss_newton
from ilc_steering.arguments import Parser
from ilc_steering.config import load_config
from ilc_steering.core.family import ModelFamily
from ilc_steering.engine.provenance import record_made

__all__ = ["Args", "main"]


@dataclass(frozen=True)
class Args:
    out: Path = Path("results/robustness")
    """Folder of ``diagnosis.json``."""
    trailer: Path = Path("results/robustness/trailer_bay")
    """The trailer map's sweep folder (its oracle and its ``robust_ilc`` rows)."""


def _servo() -> dict[str, Any]:
    config = load_config("parallel_parking_servo")
    env = gym.make("ilc_steering/ChainedSteering-v0", config=config)
    unwrapped: Any = env.unwrapped
    model = unwrapped.nominal_model
    low, high = (np.asarray(b, dtype=np.float64) for b in (unwrapped.action_space.low, unwrapped.action_space.high))
    c = model.solve()
    env.reset(seed=0)
    info = env.step(c)[4]
    geometry = ModelFamily(model)
    servo = ModelFamily(model, actuators=("steering_offset", "steering_lag"))
    y = geometry.to_configuration(model.z_goal - np.asarray(info["error"]))
    goal = geometry.to_configuration(model.z_goal)

    def fit(family: ModelFamily, starts: np.ndarray) -> tuple[np.ndarray, float]:
        def residuals(thetas: np.ndarray) -> np.ndarray:
            q, ok = family.configurations_many(thetas, np.tile(c, (len(thetas), 1)))
            return np.where(ok[:, None], q - y, 10.0)

        fits = [levenberg_marquardt(residuals, s, family.low, family.high, 40) for s in starts]
        theta, r = min(fits, key=lambda f: float(f[1] @ f[1]))
        return theta, float(np.max(np.abs(r)))

    axis = np.linspace(-np.log(2), np.log(2), 9)
    theta_g, misfit_g = fit(geometry, np.array([[a, b] for a in axis for b in axis]))
    truth = np.array([np.log(1.1), np.log(1.1), 0.02, 0.05])
    theta_s, misfit_s = fit(servo, np.array([[0, 0, o, lag] for o in (-0.04, 0.0, 0.04) for lag in (0.02, 0.05, 0.1)]))

    def configuration_error(theta: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        def residuals(cs: np.ndarray) -> np.ndarray:
            q, ok = servo.configurations_many(np.tile(theta, (len(cs), 1)), cs)
            return np.where(ok[:, None], q - goal, 10.0)

        return residuals

    steps = 1e-7 * model.action_scale()
    reached: dict[str, float] = {}
    reached["levenberg_marquardt_from_nominal_200"] = float(
        np.linalg.norm(levenberg_marquardt(configuration_error(truth), c, low, high, 200)[1])
    )
    reached["gauss_newton_from_nominal_200"] = float(
        np.linalg.norm(gauss_newton(configuration_error(truth), c, low, high, steps, 200)[1])
    )
    path = {}
    cs = c.copy()
    for s in np.linspace(0.0, 1.0, 9)[1:]:
        cs, r = levenberg_marquardt(configuration_error(s * truth), cs, low, high, 40)
        path[f"{s:.3f}"] = float(np.linalg.norm(r))
    reached["levenberg_marquardt_homotopy_8"] = path["1.000"]
    probes = c + np.vstack([np.zeros_like(c), np.diag(steps)])
    z, _ = geometry.configurations_many(np.zeros((len(probes), geometry.size)), probes)
    J = (geometry.to_chained(z[1:]) - geometry.to_chained(z[0])).T / steps
    return {
        "first_trial_error": np.asarray(info["error"]).tolist(),
        "geometry_fit": {"ratios": geometry.parameters(theta_g), "misfit": misfit_g},
        "servo_fit": {"parameters": servo.parameters(theta_s), "misfit": misfit_s},
        "true_parameters": servo.parameters(truth),
        "solver_on_the_true_model": reached,
        "homotopy_path": path,
        "jacobian_singular_values_at_nominal": np.linalg.svd(J, compute_uv=False).tolist(),
    }


def _trailer(folder: Path) -> dict[str, Any]:
    oracle = json.loads((folder / "oracle.json").read_text())
    solvable = np.array(oracle["solvable"], dtype=bool)
    rows = sorted(folder.glob("rows/robust_ilc__*.json"))
    trials = np.array([json.loads(p.read_text())["trials_to"] for p in rows])
    error = np.array([json.loads(p.read_text())["error"] for p in rows])
    left = np.array([json.loads(p.read_text())["left_chart"] for p in rows])
    lost = solvable & (trials == 0)
    run = json.loads((folder / "run.json").read_text())
    return {
        "axes": run["axes"],
        "solvable": int(solvable.sum()),
        "lost": int(lost.sum()),
        "lost_by_row": lost.sum(axis=1).tolist(),
        "lost_by_column": lost.sum(axis=0).tolist(),
        "solvable_by_row": solvable.sum(axis=1).tolist(),
        "lost_final_error_median": float(np.median(error[lost])) if lost.any() else None,
        "lost_that_ever_left_the_chart": int((left[lost] > 0).sum()),
    }


def _map(folder: Path, method: str) -> dict[str, Any]:
    """``method``'s share of the oracle-solvable plants over the rows of a map computed so far."""
    solvable = np.array(json.loads((folder / "oracle.json").read_text())["solvable"], dtype=bool)
    rows = {int(p.stem.rsplit("__", 1)[1]): json.loads(p.read_text()) for p in folder.glob(f"rows/{method}__*.json")}
    if not rows:
        return {"rows": 0}
    trials = np.array([rows[k]["trials_to"] for k in sorted(rows)])
    mask = solvable[sorted(rows)]
    converged = mask & (trials > 0)
    return {
        "rows": len(rows),
        "of_rows": int(solvable.shape[0]),
        "solvable": int(mask.sum()),
        "converged_of_solvable": float(converged.sum() / max(1, mask.sum())),
        "median_trials": float(np.median(trials[converged])) if converged.any() else None,
        "max_trials": int(trials[converged].max()) if converged.any() else None,
    }


def main(args: Args) -> dict[str, Any]:
    docs = args.trailer.parent
    maps = {
        f"{name}/{method}" if method != "robust_ilc" else name: _map(docs / name, method)
        for name in ("parallel_parking_servo", "parallel_parking_lag")
        for method in ("robust_ilc", "newton_ilc", "ilc_paper")
    }
    result = {"parallel_parking_servo": _servo(), "trailer_bay": _trailer(args.trailer), "maps": maps}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "diagnosis.json").write_text(json.dumps(result, indent=1) + "\n")
    return result


if __name__ == "__main__":
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Args.out)
    parser.add_argument("--trailer", type=Path, default=Args.trailer)
    arguments = Args(**vars(parser.parse_args()))
    print(json.dumps(main(arguments), indent=1))
    record_made(arguments.out, __file__, sys.argv[1:])
