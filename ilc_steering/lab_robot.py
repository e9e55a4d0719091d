"""Section 5's simulated MARIO as a program on the other end of a cable: ``python -m ilc_steering.lab_robot CONFIG``.

A stand-alone robot that speaks the process plant's protocol (``docs/your_robot.md``) on its stdin
and stdout: the true plant of ``CONFIG`` (a config whose plant the library simulates, e.g.
``experiment_forward``: the lab car with its servo lags, steering backlash, encoder pulses and
dead-reckoned heading), driven by each trial request. It rebuilds the trial's input profile from
the request's ``profile`` and ``c`` and simulates it with the library's own code from the
request's ``start``, as the in-process plant does; so a run on ``plant.model: process`` with this
program gives the same trials, bit for bit, as the same run in-process (the measurement noise is
drawn by the env, on the library's side, from its seed; ``tests/test_process_plant.py``).

It answers a ``hello`` with its name, each ``trial`` with a ``result`` (the final configuration,
world frame; the trajectory when the request asks to ``record``; ``left_chart`` when the
simulated robot stopped where eqs. 4-5 break down), and a request it cannot serve with an
``error``. It exits 0 when its stdin closes, 2 on a config it cannot use.
"""

from __future__ import annotations

import json
import sys
from typing import IO, Any

import numpy as np

from ilc_steering.arguments import Parser
from ilc_steering.config import SteeringConfig, load_config
from ilc_steering.core.external import is_external
from ilc_steering.core.integrate import OK
from ilc_steering.core.profiles import PiecewiseProfile
from ilc_steering.core.robots.car import rotate
from ilc_steering.core.simulate import simulate
from ilc_steering.core.trapezoid import TrapezoidProfile
from ilc_steering.errors import BadInput

__all__ = ["LabRobot", "main"]

PROTOCOL = 1


class LabRobot:
    """The true plant of a config, serving trial requests (see the module)."""

    def __init__(self, config: SteeringConfig) -> None:
        self.config = config
        self.plant = config.plant.plant()
        if is_external(self.plant):
            raise BadInput(f"{config.name}: plant.model {config.plant.model} is not a plant the library simulates")
        self.frame = config.frame() if config.plant.kind.has_pose else 0.0

    def to_task(self, q: Any) -> Any:
        return rotate(q, self.frame) if self.frame else np.array(q, dtype=np.float64)

    def to_world(self, q: Any) -> Any:
        return rotate(q, -self.frame) if self.frame else np.array(q, dtype=np.float64)

    def hello(self, message: dict[str, Any]) -> dict[str, Any]:
        robot, dimension = message.get("robot"), message.get("dimension")
        if robot != self.config.plant.model or dimension != self.config.plant.dimension:
            raise BadInput(
                f"the library's robot is {robot!r} of dimension {dimension!r}; this is a "
                f"{self.config.plant.model!r} of dimension {self.config.plant.dimension}"
            )
        return {"type": "hello", "protocol": PROTOCOL, "name": f"section 5's simulated MARIO ({self.config.name})"}

    def trial(self, message: dict[str, Any]) -> dict[str, Any]:
        spec = message["profile"]
        pieces, fixed, terms = tuple(spec["pieces"]), tuple(spec["v1_fixed"]), int(spec["v2_terms"])
        if spec["v1_shape"] == "trapezoid":
            profile: PiecewiseProfile = TrapezoidProfile(pieces, fixed, terms, float(spec["ramp"]))
        else:
            profile = PiecewiseProfile(pieces, fixed, terms)
        c = np.array(message["c"], dtype=np.float64)
        x0 = self.plant.initial_state(self.to_task(np.array(message["start"], dtype=np.float64)))
        record = bool(message.get("record", False))
        trials = simulate(self.plant, profile, x0[None], c[None], self.config.simulation.max_step, record)
        final = self.to_world(self.plant.configuration(trials.final[0]))
        left_chart = bool(trials.status[0] != OK)
        result: dict[str, Any] = {
            "type": "result",
            "trial": message["trial"],
            "final": final.tolist(),
            "left_chart": left_chart,
            "log": {"robot": self.config.name, "left_chart": left_chart},
        }
        if record and trials.times is not None and trials.states is not None:
            q = self.to_world(self.plant.configuration(trials.states[0]))
            result["trajectory"] = {"t": trials.times.tolist(), "q": q.tolist()}
        return result

    def serve(self, stdin: IO[str], stdout: IO[str]) -> None:
        """Answer every line of ``stdin`` on ``stdout`` until it closes."""
        for line in stdin:
            message = json.loads(line)
            kind = message.get("type")
            try:
                if kind == "hello":
                    answer = self.hello(message)
                elif kind == "trial":
                    answer = self.trial(message)
                else:
                    raise BadInput(f"unknown message type {kind!r}")
            except (KeyError, TypeError, ValueError) as error:
                answer = {"type": "error", "trial": message.get("trial"), "message": f"{type(error).__name__}: {error}"}
            stdout.write(json.dumps(answer) + "\n")
            stdout.flush()


def main(argv: list[str] | None = None) -> int:
    """``python -m ilc_steering.lab_robot CONFIG``: serve trials on stdin/stdout until stdin closes."""
    parser = Parser(description="section 5's simulated MARIO, speaking the process plant's protocol")
    parser.add_argument("config", help="a config whose plant the library simulates (path or packaged name)")
    args = parser.parse_args(argv)
    try:
        robot = LabRobot(load_config(args.config))
    except ValueError as error:
        print(f"lab_robot: error: {' '.join(str(error).split())}", file=sys.stderr)
        return 2
    robot.serve(sys.stdin, sys.stdout)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
