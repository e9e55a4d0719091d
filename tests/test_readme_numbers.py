"""The README's speed numbers are its committed artifacts' (``docs/benchmarks``): a table or a range
typed by hand, or left behind by a new run, fails here."""

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def section(title):
    start = README.index(title)
    end = README.find("\n### ", start + len(title))
    return README[start : end if end > 0 else None]


def test_the_every_robot_table_is_robots_json():
    rows = {r["robot"]: r for r in json.loads((ROOT / "docs/benchmarks/robots.json").read_text())["rows"]}
    text = section("### Every robot, against the car")
    lines = text.splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("| robot |"))
    table = []
    for line in lines[header + 2 :]:  # after the header and its rule, to the table's end
        if not line.startswith("| "):
            break
        table.append(line)
    assert len(table) == len(rows)
    for line in table:
        robot, task, simulated, share, floor, step = (cell.strip() for cell in line.strip("|").split("|"))
        r = rows[robot]
        assert task == r["task"]
        assert simulated == f"{r['simulated_s_per_s']:,.0f}"
        assert share == f"{r['share_of_car']:.2f}" and floor == f"{r['target_share']:.2f}"
        assert step == f"{r['step_ms']:.3f}"


def test_the_first_runs_and_frame_times_quoted_are_the_artifacts():
    text = section("### Every robot, against the car")
    firsts = json.loads((ROOT / "docs/benchmarks/robots.json").read_text())["first_run_s"]
    lab = sorted(v for k, v in firsts.items() if k.startswith("experiment_"))
    others = sorted(v for k, v in firsts.items() if not k.startswith("experiment_"))
    assert f"{others[0]:.1f}-{others[-1]:.1f} s" in text
    assert f"{lab[0]:.1f} and {lab[-1]:.1f} s" in text
    frames = json.loads((ROOT / "docs/benchmarks/render.json").read_text())["rows"]
    raster = sorted(r["raster_ms"] for r in frames)
    matplotlib = sorted(r["matplotlib_ms"] for r in frames)
    assert f"{raster[0]:.2f}-{raster[-1]:.2f} ms per frame" in text
    assert f"{matplotlib[0]:.1f}-{matplotlib[-1]:.1f} ms" in text
    assert re.search(r"under the floor of a tenth", text) and all(r["within_target"] for r in frames)


def test_the_robustness_table_is_the_committed_maps():
    # The table benchmarks/robustness.py wrote from the maps' sweep.json, and each map's own summary.
    table = (ROOT / "docs/robustness/robustness.md").read_text().strip()
    assert table in README
    for row in json.loads((ROOT / "docs/robustness/robustness.json").read_text())["rows"]:
        summary = json.loads((ROOT / "docs/robustness" / row["map"] / "sweep.json").read_text())["rows"]
        lines = {line["method"]: line for line in summary}
        assert row["solvable"] == lines["oracle"]["converged_fraction"]
        for method in ("ilc_paper", "newton_ilc", "robust_ilc"):
            assert row[f"{method}_of_solvable"] == lines[method]["of_solvable"]
            assert row[f"{method}_median"] == lines[method]["median_trials"]
