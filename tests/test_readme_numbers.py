"""The numbers of the README and of the docs pages are their committed artifacts' (``results/reproduce``,
``results/benchmarks``, ``results/robustness``): a table or a range typed by hand, or left behind by a new run, fails
here. The README fits a page, and the layout page names every module."""

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
SPEED = (ROOT / "docs/speed.md").read_text()
REPRODUCED = (ROOT / "results/reproduce/reproduce.txt").read_text()


def section(title, text=SPEED):
    start = text.index(title)
    end = text.find("\n## ", start + len(title))
    return text[start : end if end > 0 else None]


def table(text, header):
    """The rows of the Markdown table of ``text`` whose header line starts with ``header``, after its rule."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(header))
    rows = []
    for line in lines[start + 2 :]:
        if not line.startswith("| "):
            break
        rows.append(line)
    return rows


def test_the_readme_fits_a_page():
    assert len(README.splitlines()) <= 200


def test_the_reproduction_tables_are_what_reproduce_printed():
    # results/reproduce/reproduce.txt: `ilc-steering reproduce`'s output; tests/test_cli.py checks the command
    printed = table(REPRODUCED, "| scenario | paper figures |")
    assert len(printed) == 6
    paper = (ROOT / "docs/paper.md").read_text()
    for text in (README, paper):
        assert table(text, "| scenario | paper figures |") == printed
    assert "converged at trial 4" in REPRODUCED and "1.000e-01" in REPRODUCED and "1.000e-03" in REPRODUCED
    seeds = table(REPRODUCED, "| scenario | paper iterations |")
    assert len(seeds) == 2 and table(paper, "| scenario | paper iterations |") == seeds


def test_the_layout_page_names_every_module():
    layout = (ROOT / "docs/layout.md").read_text()
    folders = ("ilc_steering", "ilc_steering/core", "ilc_steering/core/robots", "envs", "agents", "benchmarks")
    missing = [
        f"{folder}/{path.name}"
        for folder in folders
        for path in sorted((ROOT / folder).glob("*.py"))
        if path.stem not in ("__init__", "__main__") and not re.search(rf"\b{path.stem}\b", layout)
    ]
    assert not missing, f"docs/layout.md does not name {missing}"


def test_the_every_robot_table_is_robots_json():
    rows = {r["robot"]: r for r in json.loads((ROOT / "results/benchmarks/robots.json").read_text())["rows"]}
    text = section("## Every robot, against the car")
    found = table(text, "| robot |")
    assert len(found) == len(rows)
    for line in found:
        robot, task, simulated, share, floor, step = (cell.strip() for cell in line.strip("|").split("|"))
        r = rows[robot]
        assert task == r["task"]
        assert simulated == f"{r['simulated_s_per_s']:,.0f}"
        assert share == f"{r['share_of_car']:.2f}" and floor == f"{r['target_share']:.2f}"
        assert step == f"{r['step_ms']:.3f}"


def test_the_first_runs_and_frame_times_quoted_are_the_artifacts():
    text = section("## Every robot, against the car")
    firsts = json.loads((ROOT / "results/benchmarks/robots.json").read_text())["first_run_s"]
    on_lab_kernel = {"parallel_parking_servo", "parallel_parking_lag"}  # the servo cars run on the lab robot's kernel
    lab = sorted(v for k, v in firsts.items() if k.startswith("experiment_") or k in on_lab_kernel)
    others = sorted(v for k, v in firsts.items() if not (k.startswith("experiment_") or k in on_lab_kernel))
    assert f"{others[0]:.1f}-{others[-1]:.1f} s" in text
    assert f"{lab[0]:.1f} and {lab[-1]:.1f} s" in text
    frames = json.loads((ROOT / "results/benchmarks/render.json").read_text())["rows"]
    raster = sorted(r["raster_ms"] for r in frames)
    matplotlib = sorted(r["matplotlib_ms"] for r in frames)
    assert f"{raster[0]:.2f}-{raster[-1]:.2f} ms per frame" in text
    assert f"{matplotlib[0]:.1f}-{matplotlib[-1]:.1f} ms" in text
    rows = json.loads((ROOT / "results/benchmarks/robots.json").read_text())["rows"]
    share, target = next((r["share_of_car"], r["target_share"]) for r in rows if r["robot"] == "lab")
    floor = "over its floor of a tenth" if share >= target else "under the floor of a tenth"
    assert floor in text and all(r["within_target"] for r in frames)


def test_the_robustness_table_is_the_committed_maps():
    # The table benchmarks/robustness.py wrote from the maps' sweep.json, and each map's own summary.
    written = (ROOT / "results/robustness/robustness.md").read_text().strip()
    assert written in (ROOT / "docs/robustness.md").read_text()
    for row in json.loads((ROOT / "results/robustness/robustness.json").read_text())["rows"]:
        lines: dict = {}
        for folder in (row["map"], row["map"] + "_others"):  # a map's methods may lie in two runs of its settings
            path = ROOT / "results/robustness" / folder / "sweep.json"
            for line in json.loads(path.read_text())["rows"] if path.exists() else []:
                lines.setdefault(line["method"], line)
        assert row["solvable"] == lines["oracle"]["converged_fraction"]
        if row["solvable"] == 1.0:  # every plant solvable: the share of the solvable is the share
            lines = {m: {**line, "of_solvable": line["converged_fraction"]} for m, line in lines.items()}
        for method in ("ilc_paper", "newton_ilc", "robust_ilc"):
            assert row[f"{method}_of_solvable"] == lines[method]["of_solvable"]
            assert row[f"{method}_median"] == lines[method]["median_trials"]


def test_the_test_tiers_times_are_the_logged_runs():
    text = " ".join((ROOT / "docs/tests.md").read_text().split())  # wherever the page's lines wrap
    log = (ROOT / "results/benchmarks/test_tiers/fast.txt").read_text()
    passed, seconds = re.search(r"(\d+) passed, \d+ deselected, .* in ([\d.]+)s", log).groups()
    user, sys_ = re.search(r"user ([\d.]+) s, sys ([\d.]+) s", log).groups()
    loads = re.findall(r"load average: ([\d.]+),", log)
    assert f"ran {passed} tests in {seconds} s" in text
    assert f"{float(user) + float(sys_):.1f} s of CPU time (user {user} s, sys {sys_} s)" in text
    assert f"(load average {loads[0]} at the start, {loads[-1]} at the end)" in text


def test_the_slow_tiers_time_is_the_logged_run():
    text = " ".join((ROOT / "docs/tests.md").read_text().split())
    log = (ROOT / "results/benchmarks/test_tiers/slow.txt").read_text()
    found = re.search(r"(?:(\d+) failed, )?(\d+) passed, \d+ deselected, .* in ([\d.]+)s", log)
    assert found is not None, "the slow tier's log has no pytest summary"
    failed, passed, seconds = int(found[1] or 0), int(found[2]), found[3]
    user, sys_ = re.search(r"user ([\d.]+) s, sys ([\d.]+) s", log).groups()
    loads = re.findall(r"load average: ([\d.]+),", log)
    assert f"{failed + passed} tests in {seconds} s, on {float(user) + float(sys_):.1f} s of CPU time" in text
    assert f"(load average {loads[0]} at the start, {loads[-1]} at the end)" in text
    assert ("failed there" in text) == bool(failed)  # a failure of the logged run is named on the page


def test_the_mujoco_page_quotes_its_artifacts():
    # benchmarks/mujoco_car.py's tables, as written; and the page's words match their numbers.
    page = (ROOT / "docs/mujoco.md").read_text()
    for stem in ("mujoco_repeatability", "mujoco_learners", "mujoco_spread"):
        assert (ROOT / f"results/mujoco/{stem}.md").read_text().strip() in page, stem
    runs = json.loads((ROOT / "results/mujoco/mujoco_learners.json").read_text())["rows"]
    smooth = [r for r in runs if not r["config"].endswith("_scatter")]
    assert all(r["trials_to_1cm"] <= 2 and r["last_inside"] for r in smooth)
    scattered = [r["last_worst_m"] for r in runs if r["config"].endswith("_scatter")]
    assert f"{1e3 * min(scattered):.1f}-{1e3 * max(scattered):.1f} mm" in page
    speed = [
        r["simulated_per_wall"]
        for r in json.loads((ROOT / "results/mujoco/mujoco_repeatability.json").read_text())["rows"]
    ]
    assert f"{min(speed):.0f}-{max(speed):.0f} simulated seconds per wall second" in page


def test_the_highway_tables_are_the_artifacts(monkeypatch):
    # issue 50 item 5: one table of every method on parking-v0's goals, from results/highway's artifacts
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    monkeypatch.chdir(ROOT)
    import highway_table

    blocks = highway_table.tables(ROOT / "results/highway")
    for path in (ROOT / "README.md", ROOT / "docs/highway.md"):
        text = path.read_text()
        assert highway_table.render(text, blocks, str(path)) == text, (
            f"python benchmarks/highway_table.py --into {path}"
        )
    assert "<!-- highway-table: summary -->" in README
    assert "<!-- highway-table: her-curve -->" in (ROOT / "docs/highway.md").read_text()


def test_the_map_tables_are_the_artifacts(monkeypatch):
    # issue 52 item 5: the robustness and sweep tables of the docs generated from the committed maps
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    import map_tables

    from ilc_steering.tables import render_blocks

    blocks = map_tables.tables(ROOT / "results")
    for path, names in (
        (ROOT / "docs/robustness.md", ("robustness", "sweep", "sweep-blackbox")),
        (ROOT / "docs/diagnosis.md", ("diagnosis-maps",)),
    ):
        text = path.read_text()
        assert render_blocks(text, blocks, map_tables.KIND, str(path)) == text, (
            f"python benchmarks/map_tables.py --into {path}"
        )
        for name in names:
            assert f"<!-- map-table: {name} -->" in text
