"""A robot program is a child the library owns (issue 64).

A fake robot (a small script in tmp_path) answers the process plant's protocol in hostile ways: it
stops reading while a request bigger than the pipe is on its way, it starts children of its own, it
sends logs of megabytes, it reports its heading unwrapped or in degrees. Each case ends in one line
with exit 2 or 4, or in success; nothing run is lost; and no process of it is left running (read
from ``/proc``: a process gone, or a zombie nobody reaps in a container, is not running).
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.core.plants import CHART_MARGIN
from ilc_steering.core.robots.car import CAR
from ilc_steering.core.robots.process_limits import (
    MAX_LOG_BYTES,
    MAX_SAMPLES,
    MAX_TURNS,
    ProcessLimits,
    kept_log,
    reported_pose,
    reported_trajectory,
)
from ilc_steering.errors import PlantError

ROBOT = r"""
import json, math, os, subprocess, sys, time

mode, at, value = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(3600)"])  # a child of its own
with open("pids.txt", "a") as f:
    f.write(f"{os.getpid()} {child.pid}\n")
for line in sys.stdin:
    request = json.loads(line)
    if request["type"] == "hello":
        print(json.dumps({"type": "hello", "protocol": 1, "name": "fake"}), flush=True)
        if mode == "stops_reading":
            time.sleep(3600)
        continue
    k, final = request["trial"], list(request["nominal"]["q"][-1])
    answer = {"type": "result", "trial": k, "final": final}
    if k >= at and mode == "hangs":
        time.sleep(3600)
    if mode == "big_log":
        answer["log"] = {"samples": "x" * 12_000_000}
    if mode == "turns":
        final[2] += 2 * math.pi * (k % 3 - 1)
    if mode == "heading" and k >= at:
        final[2] = value
    print(json.dumps(answer), flush=True)
"""


pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc")


def write_config(
    where: Path,
    mode: str,
    at: int = 0,
    value: float = 0.0,
    timeout: float = 5.0,
    executable: bool = False,
    **plant: Any,
) -> Path:
    """forward_parking's task on the fake robot in ``where`` (``executable``: run as ``./robot.py``)."""
    (where / "robot.py").write_text(f"#!{sys.executable}\n{ROBOT}")
    (where / "robot.py").chmod(0o755)
    program = ["./robot.py"] if executable else ["python", "robot.py"]
    data = {
        "name": "fake_robot",
        "plant": {
            "model": "process",
            "command": [*program, mode, str(at), repr(value)],
            "timeout": timeout,
            "robot": {
                "model": "car",
                "wheelbase": 0.2,
                "wheel_radius": 0.02,
                "true_wheelbase": 0.2,
                "true_wheel_radius": 0.02,
            },
            "limits": {"workspace": [-3.0, 3.0, -3.0, 3.0], "speed": 1.0, "steering": 1.5, "steering_rate": 5.0},
            **plant,
        },
        "task": {
            "start": [-1.0, 0.0, 0.7853981633974483, 0.0],
            "goal": [0.0, 0.0, 0.7853981633974483, 0.0],
            "pieces": [5.0],
            "v1_fixed": [],
            "v2_terms": 3,
        },
        "learning": {"nu_a": 1.0, "nu_b": 1.0, "trials": 4, "tolerance": {"cartesian": 5e-4, "orientation": 5e-4}},
    }
    path = where / "fake_robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def running(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")


def left_running(folder: Path) -> list[int]:
    """The fake robots' processes and their children still running, a little after they were stopped."""
    pids = [int(p) for p in (folder / "pids.txt").read_text().split()] if (folder / "pids.txt").exists() else []
    deadline = time.monotonic() + 10
    while any(running(pid) for pid in pids) and time.monotonic() < deadline:  # SIGKILL is asynchronous
        time.sleep(0.05)
    return [pid for pid in pids if running(pid)]


def one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_a_program_that_stops_reading_a_request_bigger_than_the_pipe_is_stopped_at_the_timeout(tmp_path, capsys):
    config = write_config(tmp_path, "stops_reading", timeout=1.0, control_rate=2000.0)  # a request of some MB
    assert main(["run", str(config), "--trials", "3"]) == 4
    assert "stopped reading trial 1: it took" in one_line(capsys)
    assert not left_running(tmp_path)


def test_a_program_and_what_it_started_are_stopped_when_the_run_ends(tmp_path, capsys):
    assert main(["run", str(write_config(tmp_path, "honest")), "--json", str(tmp_path / "run.json")]) in (0, 1)
    assert len((tmp_path / "pids.txt").read_text().split()) == 2 and not left_running(tmp_path)


def test_sigterm_to_run_keeps_the_trials_as_ctrl_c_does_and_stops_the_program(tmp_path, capsys, monkeypatch):
    """SIGTERM arrives after the second trial's row (as a supervisor would send it mid-run)."""
    from ilc_steering import console

    rows: list[Any] = []
    real = console.print_row

    def row_then_sigterm(record: Any) -> None:
        real(record)
        rows.append(record)
        if len(rows) == 2:
            signal.raise_signal(signal.SIGTERM)

    monkeypatch.setattr(console, "print_row", row_then_sigterm)
    out, before = tmp_path / "run.json", signal.getsignal(signal.SIGTERM)
    assert main(["run", str(write_config(tmp_path, "hangs", at=3)), "--json", str(out)]) == 130
    assert "terminated by SIGTERM after 2 trials; what ran is kept in" in one_line(capsys)
    assert len(json.loads(out.read_text())["trials"]) == 2
    assert not left_running(tmp_path)
    assert signal.getsignal(signal.SIGTERM) == before  # the CLI's handler is gone with it


@pytest.mark.slow  # a fresh interpreter runs the CLI, signalled from outside
def test_sigterm_to_the_command_keeps_the_trials_and_stops_the_program(tmp_path):
    out = tmp_path / "run.json"
    command = [
        sys.executable,
        "-m",
        "ilc_steering",
        "run",
        str(write_config(tmp_path, "hangs", at=3)),
        "--json",
        str(out),
    ]
    run = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    assert run.stdout is not None
    rows = 0
    for line in run.stdout:  # the header, the column names, then a row per trial
        rows += line.split()[:1] in (["1"], ["2"])
        if rows == 2:
            break
    run.send_signal(signal.SIGTERM)
    _, err = run.communicate(timeout=60)
    assert run.returncode == 130 and "terminated by SIGTERM after 2 trials" in err
    assert len(json.loads(out.read_text())["trials"]) == 2
    assert not left_running(tmp_path)


@pytest.mark.slow  # worker processes
def test_a_cell_past_its_time_limit_takes_its_robot_program_with_it(tmp_path, capsys):
    config = write_config(tmp_path, "hangs", at=2, timeout=600.0)
    argv = ["compare", "--scenarios", str(config), "--methods", "ilc", "--seeds", "1", "--priors", "nominal"]
    argv += ["--model-trials", "3", "--cell-timeout", "10", "--workers", "1", "--out", str(tmp_path / "c")]
    assert main(argv) == 4
    assert "CallTimeout" in "".join(capsys.readouterr())
    assert len((tmp_path / "pids.txt").read_text().split()) == 2 and not left_running(tmp_path)


@pytest.mark.slow  # 72 MB through a pipe and back from disk
def test_megabytes_of_logs_make_a_run_record_that_plot_reads(tmp_path, capsys):
    out = tmp_path / "run.json"
    assert (
        main(["run", str(write_config(tmp_path, "big_log")), "--trials", "6", "--hold", "1", "--json", str(out)]) == 0
    )
    logs = [trial["plant"] for trial in json.loads(out.read_text())["trials"]]
    assert all(log == {"dropped": f"a log of 12000015 bytes, over the {MAX_LOG_BYTES} kept"} for log in logs)
    assert main(["plot", str(out), "--out", str(tmp_path / "figures")]) == 0


def test_a_process_run_is_plotted_after_its_program_has_moved(tmp_path, capsys):
    out = tmp_path / "run.json"
    assert main(["run", str(write_config(tmp_path, "honest", executable=True)), "--json", str(out)]) in (0, 1)
    (tmp_path / "robot.py").rename(tmp_path / "elsewhere.py")  # ./robot.py is no program any more
    assert main(["plot", str(out), "--out", str(tmp_path / "figures")]) == 0


def test_a_relative_plant_folder_is_the_configs_not_the_working_directorys(tmp_path, monkeypatch, capsys):
    (tmp_path / "lab").mkdir()
    config = write_config(tmp_path / "lab", "honest", folder="lab")
    config = config.rename(tmp_path / "fake_robot.yaml")
    monkeypatch.chdir(tmp_path / "lab")  # run from elsewhere: "lab" would be lab/lab
    assert Path(load_config(str(config)).plant.folder) == tmp_path / "lab"
    assert main(["run", str(config), "--trials", "3"]) in (0, 1)


# -- what a program reports, as properties --------------------------------------------------------

LIMITS = ProcessLimits((-3.0, 3.0, -3.0, 3.0), 1.0, 1.5, 5.0)
EDGE = math.pi / 2 - CHART_MARGIN


def _fail(problem: str) -> Exception:
    return PlantError(problem)


@settings(max_examples=300, deadline=None)
@given(
    heading=st.floats(-EDGE + 1e-6, EDGE - 1e-6),
    turns=st.integers(-MAX_TURNS + 1, MAX_TURNS - 1),
    frame=st.floats(-1.0, 1.0),
)
def test_a_heading_unwrapped_by_whole_turns_is_read_wrapped_and_the_wrap_stated(heading, turns, frame):
    world = heading + frame + 2 * math.pi * turns
    q, left, wrapped = reported_pose(LIMITS, CAR, [0.1, 0.2, world, 0.05], frame, "trial 1", _fail)
    assert q[2] == pytest.approx(heading, abs=1e-12) and not left
    assert bool(wrapped) == (turns != 0)
    if turns:
        assert wrapped["θ"][0] == world and wrapped["θ"][1] == pytest.approx(heading + frame, abs=1e-12)


@settings(max_examples=200, deadline=None)
@given(angle=st.floats(allow_nan=False, allow_infinity=False), steering=st.booleans())
def test_an_angle_is_read_in_the_chart_left_the_chart_or_refused_as_no_radians(angle, steering):
    final = [0.1, 0.2, 0.3, angle] if steering else [0.1, 0.2, angle, 0.05]
    bound = math.pi if steering else 2 * math.pi * MAX_TURNS
    try:
        q, left, _ = reported_pose(LIMITS, CAR, final, 0.0, "trial 1", _fail)
    except PlantError as error:
        assert abs(angle) > bound and "not an angle in radians (in degrees?" in str(error)
        return
    assert abs(angle) <= bound and np.all(np.abs(q[2:]) <= EDGE) and np.all(np.isfinite(q))
    assert left == (abs(angle if steering else math.remainder(angle, 2 * math.pi)) > EDGE)


@pytest.mark.parametrize("heading", [45.0, 1e9, -90.0])
def test_a_heading_in_degrees_ends_the_run_naming_the_program_not_the_limits(tmp_path, capsys, heading):
    assert main(["run", str(write_config(tmp_path, "heading", at=2, value=heading)), "--trials", "3"]) == 4
    err = one_line(capsys)
    assert "reported trial 2's θ as" in err and "in degrees?" in err and "plant.limits" not in err
    assert not left_running(tmp_path)


def test_headings_reported_unwrapped_run_as_wrapped_ones_and_say_so(tmp_path, capsys):
    assert main(["run", str(write_config(tmp_path, "turns")), "--trials", "3"]) in (0, 1)
    out = capsys.readouterr().out
    assert out.count(" rad read as ") == 2  # trial 1 as it is, trial 2 a turn more, trial 3 a turn less


@settings(max_examples=50, deadline=None)
@given(size=st.integers(0, 3 * MAX_LOG_BYTES), samples=st.integers(2, 5 * MAX_SAMPLES))
def test_what_a_trial_keeps_of_a_program_is_bounded(size, samples):
    log = kept_log({"text": "x" * size})
    assert len(json.dumps(log)) <= MAX_LOG_BYTES
    t = list(np.linspace(0.0, 5.0, samples))
    path = reported_trajectory({"t": t, "q": [[v, 0.0, 0.0, 0.0] for v in t]}, 4, "trial 1", _fail)
    assert path is not None and len(path[0]) == min(samples, MAX_SAMPLES)
    assert path[0][0] == 0.0 and path[0][-1] == 5.0 and np.all(np.diff(path[0]) > 0)


READER = r"""
import os, sys, time
wanted, got = int(sys.argv[1]), 0
while got < wanted:
    chunk = os.read(0, min(65536, wanted - got))
    if not chunk:
        break
    got += len(chunk)
time.sleep(3600)  # then it reads no more, and never exits by itself
"""


@pytest.mark.slow  # a program per example, and a deadline each
@pytest.mark.timeout(600)
@settings(max_examples=30, deadline=None)
@given(size=st.integers(1, 4 << 20), read=st.integers(0, 4 << 20))
def test_a_request_is_taken_whole_or_refused_at_the_deadline_and_the_program_stopped(tmp_path_factory, size, read):
    """Whatever part of a request a program reads before it stops reading, ``send`` returns (the rest
    fits the pipe) or raises one PlantError at ``plant.timeout``; never hangs; the program is gone after."""
    from ilc_steering.core.cable import Cable

    folder = tmp_path_factory.mktemp("reader")
    cable = Cable([sys.executable, "-c", READER, str(read)], str(folder))
    try:
        cable.send({"type": "trial", "blob": "x" * size}, "trial 1", 0.5)
    except PlantError as error:
        assert "stopped reading trial 1: it took" in str(error) and "\n" not in str(error)
        assert read < size  # refused only if it did stop reading before the end
    finally:
        cable.close(kill=True)
    assert not running(cable.process.pid)
