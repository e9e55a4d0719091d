"""The picture of docs/usage.md's TensorBoard section: an ILC cell and a PPO cell of one comparison, as
their event files hold them.

Runs ``ilc-steering compare --methods ilc ppo --scenarios forward_parking --seeds 0 --priors nominal
--tensorboard DIR`` (in a temporary folder), reads both cells' event files back with TensorBoard's own
reader, and draws the tags of :data:`TAGS` against the trial (TensorBoard's step, on a log axis: 10
ILC trials beside 300 PPO trials) with matplotlib, one line per cell, as TensorBoard lays them on one
chart:

    python benchmarks/tensorboard_chart.py [--quick] [--out docs/figures]

writes ``tensorboard_forward_parking.png`` and ``made.json`` in ``--out``.
"""

from __future__ import annotations

import sys
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

from ilc_steering.arguments import Parser
from ilc_steering.engine.provenance import record_made

__all__ = ["Args", "main"]

TAGS = ("trial/true_cartesian_error", "trial/cost", "trial/converged")
"""The tags drawn, one panel each (forward_parking's orientation error is round-off for ILC: its
nominal solution already meets the goal's heading)."""
UNITS = {"trial/true_cartesian_error": "[m]", "trial/cost": "[m + rad]", "trial/converged": "0 or 1"}


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """``compare --quick``'s budgets (6 ILC trials, 48 PPO trials): checks that the script runs (CI)."""
    rl_trials: int = 300
    """PPO's budget [trials] (without ``quick``)."""
    model_trials: int = 10
    """ILC's budget [trials] (without ``quick``)."""
    out: Path = Path("docs/figures")
    """Where the picture goes."""


def series(folder: Path) -> dict[str, list[tuple[int, float]]]:
    """tag -> [(step, value)] of the event files in ``folder``, every point kept."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    from tensorboard.util import tensor_util

    accumulator = EventAccumulator(str(folder), size_guidance={"tensors": 0})
    accumulator.Reload()
    return {
        tag: [(event.step, float(tensor_util.make_ndarray(event.tensor_proto))) for event in accumulator.Tensors(tag)]
        for tag in accumulator.Tags()["tensors"]
    }


def main(args: Args) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ilc_steering.compare.args import Args as CompareArgs
    from ilc_steering.compare.command import main as compare
    from ilc_steering.compare.command import method_families
    from ilc_steering.figure_styles import method_styles
    from ilc_steering.trial_board import run_folder

    with tempfile.TemporaryDirectory() as work:
        board = Path(work) / "tensorboard"
        settings = CompareArgs(
            quick=args.quick,
            out=Path(work) / "run",
            priors=("nominal",),
            methods=("ilc", "ppo"),
            scenarios=("forward_parking",),
            seeds=(0,),
            workers=1,
            tensorboard=board,
        )
        if not args.quick:
            settings = replace(settings, rl_trials=args.rl_trials, model_trials=args.model_trials)
        compare(settings)
        read = {method: series(run_folder(board, "forward_parking", method, 0)) for method in ("ilc", "ppo")}
    figure, axes = plt.subplots(1, len(TAGS), figsize=(13, 3.8), constrained_layout=True)
    styles = method_styles(list(read), method_families(read))  # compare's own colours: ILC blue, RL red
    for ax, tag in zip(axes, TAGS):
        for method, tags in read.items():
            steps, values = zip(*tags[tag])
            style = styles[method]
            ax.plot(
                steps,
                values,
                label=f"forward_parking/{method}_seed0",
                color=style.colour,
                marker=style.marker,
                linestyle=style.linestyle,
                markersize=3,
            )
        ax.set_xscale("log")
        if tag == "trial/converged":
            ax.set_ylim(-0.1, 1.1)
        else:
            ax.set_yscale("log")
        ax.set_title(tag)
        ax.set_xlabel("trial (TensorBoard's step)")
        ax.set_ylabel(UNITS[tag])
        ax.grid(True, which="major", alpha=0.3)
    axes[0].legend(title="run", fontsize=8)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "tensorboard_forward_parking.png"
    figure.savefig(path, dpi=110)
    plt.close(figure)
    print(f"wrote {path}")
    return path


if __name__ == "__main__":
    parser = Parser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--rl-trials", type=int, default=Args.rl_trials)
    parser.add_argument("--model-trials", type=int, default=Args.model_trials)
    parser.add_argument("--out", type=Path, default=Args.out)
    cli = parser.parse_args()
    main(Args(cli.quick, cli.rl_trials, cli.model_trials, cli.out))
    record_made(cli.out, __file__, sys.argv[1:])
