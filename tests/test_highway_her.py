"""HER's learning curve (benchmarks/highway_her.py, issue 50 item 4): a resumed curve is the same
computation as one run straight through, and a folder of other settings is refused."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "highway_her.py"


def _her(out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    argv = [sys.executable, str(SCRIPT), "--quick", "--out", str(out), "--models", str(out / "models"), *extra]
    return subprocess.run(argv, capture_output=True, text=True, timeout=900)


@pytest.mark.slow
@pytest.mark.extra("rl", "highway")
def test_a_curve_resumed_in_a_new_process_is_the_curve_run_straight_through(tmp_path: Path) -> None:
    straight, resumed = tmp_path / "straight", tmp_path / "resumed"
    assert _her(straight).returncode == 0
    assert _her(resumed, "--steps", "150").returncode == 0  # the first chunk, then the process ends
    assert sorted(p.name for p in (resumed / "highway_her_quick_curve").iterdir()) == ["seed0_0000150.json"]
    assert _her(resumed).returncode == 0  # the second chunk, from the checkpoint on disk
    for name in ("seed0_0000150.json", "seed0_0000300.json"):
        a, b = (json.loads((run / "highway_her_quick_curve" / name).read_text()) for run in (straight, resumed))
        assert a["goals"] == b["goals"] and a["fingerprint"] == b["fingerprint"], name
    assert (resumed / "highway_her_quick.md").read_text().count("| 300 |") == 1
    rows = json.loads((resumed / "highway_her_quick.json").read_text())["rows"]
    assert {r["steps"] for r in rows} == {150, 300}  # the training steps; a goal's episode has its own key
    assert all(1 <= r["episode_steps"] <= 100 for r in rows)


@pytest.mark.extra("rl", "highway")
@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_a_folder_of_other_settings_is_refused_in_one_line(tmp_path: Path) -> None:
    curve = tmp_path / "highway_her_quick_curve"
    curve.mkdir()
    (curve / "seed0_0000150.json").write_text(json.dumps({"seed": 0, "steps": 150, "fingerprint": "0" * 16}))
    done = _her(tmp_path)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "other settings or versions" in done.stderr
