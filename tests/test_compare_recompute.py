"""The committed comparison (``results/compare``) recomputes: one cell per method, the cheapest of each,
run again by today's code, gives the committed trials bit for bit wherever its code says it is
current. A cell whose closure changed since it was made is stale, and ``ilc-steering current``
must say so (it is recomputed by a resume); a cell said current that does not recompute bit for
bit would be a closure that misses a file the cell depends on."""

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
COMPARE = ROOT / "results" / "compare"
KEYS = ("trials", "trials_to", "best_error", "curve", "off_chart_fraction", "clipped_fraction", "fragile")
EXTRAS = {"bayes_opt": "botorch", "cma_es": "cma", "ppo": "stable_baselines3", "sac": "stable_baselines3",
          "td3": "stable_baselines3", "tqc": "sb3_contrib"}  # fmt: skip


def cheapest_cells():
    cells = json.loads((COMPARE / "compare.json").read_text())["cells"]
    best = {}
    for cell in cells:
        if cell["method"] not in best or cell["wall_s"] < best[cell["method"]]["wall_s"]:
            best[cell["method"]] = cell
    return [pytest.param(cell, id=method) for method, cell in sorted(best.items())]


@pytest.mark.slow  # about a minute: an RL cell is 5000 trials
@pytest.mark.parametrize("committed", cheapest_cells())
def test_a_committed_cell_recomputes_bit_for_bit_or_is_said_stale(committed):
    from ilc_steering.compare.args import Args
    from ilc_steering.compare.cells import run_cell

    module = EXTRAS.get(committed["method"])
    if module is not None and importlib.util.find_spec(module) is None:
        pytest.skip(f"{committed['method']} needs {module} (an extra)")
    from ilc_steering.current import check_folders
    from ilc_steering.engine.provenance import read_run
    from ilc_steering.engine.staleness import configs_today, staleness

    settings, record = read_run(COMPARE)
    if staleness(committed, record.codes, configs_today([committed["scenario"]])):
        current, lines = check_folders([COMPARE])
        assert not current and any(f"of {committed['method']}:" in line for line in lines), lines
        return  # stale, and said to be: a resume recomputes it
    budgets = {key: settings[key] for key in ("model_trials", "blackbox_trials", "rl_trials", "custom_trials")}
    args = Args(**budgets)
    cell = run_cell(args, committed["prior"], committed["method"], committed["scenario"], committed["seed"])
    assert cell["budget"] == committed["budget"]
    for key in KEYS:
        assert json.loads(json.dumps(cell[key])) == committed[key], key
