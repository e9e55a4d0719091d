"""``plant.model: process``: a plant that is another program (docs/your_robot.md).

A tiny fake robot (a Python script written to tmp_path) answers the protocol honestly, or in one
of the hostile ways a real program may: each is one clear line naming the program, exit 4, the
trial not counted and the trials before it written. Commands beyond the robot's limits are
refused before anything is sent (exit 2). The slow tier checks that section 5's MARIO as a
program (``python -m ilc_steering.lab_robot``) gives the in-process trials bit for bit.
"""

import json
import sys

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.core.robots.process import ProcessPlant
from ilc_steering.core.robots.process_request import nominal_path
from ilc_steering.runner import run_ilc

ROBOT = r"""
import json, math, os, sys, time

mode, fail_at = sys.argv[1], int(sys.argv[2])
with open("starts.txt", "a") as f:
    f.write(f"{os.getpid()}\n")

def say(message, end="\n"):
    sys.stdout.write(json.dumps(message) + end)
    sys.stdout.flush()

for line in sys.stdin:
    with open("received.jsonl", "a") as f:
        f.write(line)
    request = json.loads(line)
    if request["type"] == "hello":
        say({"type": "hello", "protocol": 1, "name": "fake"} if mode != "bad_hello" else {"type": "hi"})
        continue
    k = request["trial"]
    final = request["nominal"]["q"][-1]  # the nominal model's own final pose: an honest robot
    answer = {"type": "result", "trial": k, "final": final, "log": {"mode": mode}}
    if k == fail_at:
        if mode == "hang":
            time.sleep(3600)
        elif mode == "dies":
            sys.exit(3)
        elif mode == "garbage":
            sys.stdout.write("moving... done\n")
            sys.stdout.flush()
            continue
        elif mode == "half_line":
            sys.stdout.write('{"type": "result", "tri')
            sys.stdout.flush()
            sys.exit(0)
        elif mode == "closes_stdout":
            os.close(1)
            time.sleep(3600)
        elif mode == "stale":
            answer["trial"] = k - 1
        elif mode == "nan":
            answer["final"] = [math.nan, *final[1:]]
        elif mode == "inf":
            answer["final"] = [final[0], math.inf, *final[2:]]
        elif mode == "overflow":  # valid JSON, a number no float holds
            line = json.dumps({**answer, "final": [final[0], 12345.0, *final[2:]]})
            sys.stdout.write(line.replace("12345.0", "1e400") + "\n")
            sys.stdout.flush()
            continue
        elif mode == "kilometre":
            answer["final"] = [final[0] + 1000.0, *final[1:]]
        elif mode == "wrong_length":
            answer["final"] = final[:3]
        elif mode == "refuses":
            answer = {"type": "error", "trial": k, "message": "bumper hit the wall"}
        elif mode == "not_an_object":
            answer = [1, 2, 3]
    say(answer)
"""

HOSTILE = {
    "hang": r"gave no answer to trial 2 within plant\.timeout = 1 s",
    "dies": r"died before answering trial 2 \(exit status 3\)",
    "garbage": r"answered trial 2 with a line that is not JSON .*'moving\.\.\. done'",
    "half_line": r"wrote half a line \('\{\"type\": \"result\", \"tri', no newline\)",
    "closes_stdout": r"closed its stdout before answering trial 2 \(it was still running; it is stopped\)",
    "stale": r"answered trial 1 to trial 2's request \(a stale or wrong answer\)",
    "nan": r"answered trial 2 with a line that is not JSON \(NaN is not a number JSON allows\)",
    "inf": r"answered trial 2 with a line that is not JSON \(Infinity is not a number JSON allows\)",
    "overflow": r"answered trial 2 with final = \[.*, inf, .*\]: it needs 4 finite numbers",
    "kilometre": r"reported trial 2's final pose at \(x, y\) = \(1000.*\) m, outside plant\.limits\.workspace",
    "wrong_length": r"answered trial 2 with final = .*: it needs 4 finite numbers",
    "refuses": r"says trial 2 failed: bumper hit the wall",
    "not_an_object": r"answered trial 2 with JSON that is not an object",
}


def write_config(tmp_path, mode="honest", fail_at=0, timeout=5.0, **limits):
    """forward_parking's task on the fake robot, in ``tmp_path`` (the program's working directory)."""
    (tmp_path / "robot.py").write_text(ROBOT)
    data = {
        "name": "fake_robot",
        "plant": {
            "model": "process",
            "command": ["python", "robot.py", mode, str(fail_at)],
            "timeout": timeout,
            "robot": {
                "model": "car",
                "wheelbase": 0.2,
                "wheel_radius": 0.02,
                "true_wheelbase": 0.2,
                "true_wheel_radius": 0.02,
            },
            "limits": {"workspace": [-3.0, 3.0, -3.0, 3.0], "speed": 1.0, "steering": 1.5, "steering_rate": 5.0}
            | limits,
        },
        "task": {
            "start": [-1.0, 0.0, 0.7853981633974483, 0.0],
            "goal": [0.0, 0.0, 0.7853981633974483, 0.0],
            "pieces": [5.0],
            "v1_fixed": [],
            "v2_terms": 3,
        },
        "learning": {"nu_a": 1.0, "nu_b": 1.0, "trials": 3, "tolerance": {"cartesian": 5e-4, "orientation": 5e-4}},
    }
    path = tmp_path / "fake_robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def received(tmp_path):
    path = tmp_path / "received.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def starts(tmp_path):
    path = tmp_path / "starts.txt"
    return path.read_text().split() if path.exists() else []


def test_the_round_trip_one_start_and_one_request_per_counted_trial(tmp_path):
    config = write_config(tmp_path)
    result = run_ilc(config, trials=3)
    assert len(result.trials) == 3 and result.converged_at == 1  # the fake robot is the nominal model
    messages = received(tmp_path)
    assert len(starts(tmp_path)) == 1
    assert [m["type"] for m in messages] == ["hello", "trial", "trial", "trial"]
    assert messages[0] == {"type": "hello", "protocol": 1, "robot": "car", "dimension": 4}
    assert [m["trial"] for m in messages[1:]] == [1, 2, 3]
    first = messages[1]
    assert first["start"] == [-1.0, 0.0, 0.7853981633974483, 0.0]  # world frame
    assert first["c"] == result.trials[0].action
    assert first["profile"] == {"pieces": [5.0], "v1_fixed": [], "v2_terms": 3, "v1_shape": "constant", "ramp": None}
    control = first["control"]
    assert control["dt"] == 0.02 and len(control["t"]) == 251 and control["t"][-1] == 5.0
    assert len(first["nominal"]["q"]) == len(first["nominal"]["u1"]) == 251
    # the pose it reported is the pose recorded (no measurement noise), and its log comes along
    assert result.trials[0].final_state == first["nominal"]["q"][-1]
    assert result.trials[0].plant == {"mode": "honest"}


def test_the_nominal_path_ends_where_the_nominal_model_says(tmp_path):
    """Without a steering stop, the nominal plant's path ends within 1e-9 of eq. 12's closed form."""
    from ilc_steering.envs.scenario import Scenario

    config = load_config(write_config(tmp_path))
    scenario = Scenario.from_config(config)
    model, plant = scenario.nominal, scenario.plant
    c = model.solve()
    times, q, _ = nominal_path(plant.nominal, model.profile, scenario.x_start, c, 0.002)
    assert times[0] == 0.0 and times[-1] == 5.0 and np.max(np.diff(times)) <= 0.002 + 1e-15
    assert np.max(np.abs(model.chained_map.to_chained(q[-1]) - model.final_state(c))) < 1e-9
    assert np.max(np.abs(q[-1] - np.array(config.task.goal))) < 1e-9


def test_the_nominal_path_stops_the_wheel_at_the_robots_steering_stop(tmp_path):
    """With a steering limit the path is the nominal car's with its stop: |phi| never past it."""
    from ilc_steering.envs.scenario import Scenario

    scenario = Scenario.from_config(load_config("experiment_parallel_process"))
    c = 3.0 * scenario.nominal.solve()
    _, q, _ = nominal_path(scenario.plant.nominal, scenario.profile, scenario.x_start, c, 0.002)
    assert np.max(np.abs(q[:, 3])) == pytest.approx(0.4363323129985824)


@pytest.mark.parametrize("mode", sorted(HOSTILE))
def test_a_hostile_program_is_one_line_exit_4_and_the_trial_not_counted(tmp_path, capsys, mode):
    config = write_config(tmp_path, mode, fail_at=2, timeout=1.0 if mode == "hang" else 10.0)
    out = tmp_path / "run.json"
    code = main(["run", str(config), "--trials", "3", "--json", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 4
    assert len(err) == 1 and err[0].startswith("ilc-steering: plant process 'python robot.py")
    assert __import__("re").search(HOSTILE[mode], err[0]), err[0]
    run = json.loads(out.read_text())
    assert [t["trial"] for t in run["trials"]] == [1]  # trial 2 not counted; trial 1 kept
    assert len(starts(tmp_path)) == 1
    assert [m.get("trial") for m in received(tmp_path)] == [None, 1, 2]  # nothing after the failure


def test_a_bad_hello_and_a_program_that_cannot_start(tmp_path, capsys):
    config = write_config(tmp_path, "bad_hello")
    assert main(["run", str(config), "--trials", "1", "--hold", "1"]) == 4
    err = capsys.readouterr().err
    assert "answered the hello with {'type': 'hi'}" in err and [m["type"] for m in received(tmp_path)] == ["hello"]
    data = yaml.safe_load(config.read_text())
    data["plant"]["command"] = ["./no_such_robot"]
    config.write_text(yaml.safe_dump(data))
    assert main(["run", str(config)]) == 2
    assert "plant.command: './no_such_robot' is not an executable file" in capsys.readouterr().err


@pytest.mark.parametrize(
    "limit, message",
    [
        ({"speed": 0.05}, r"plant\.limits\.speed: trial 1's nominal path needs 0\.\d+ m/s at t = .* s, beyond"),
        ({"steering": 0.05}, r"plant\.limits\.steering: trial 1's nominal path needs \|phi\| = "),
        ({"steering_rate": 0.01}, r"plant\.limits\.steering_rate: trial 1's nominal path needs "),
        ({"workspace": [-3.0, -0.5, -3.0, 3.0]}, r"plant\.limits\.workspace: trial 1's nominal path needs \(x, y\)"),
    ],
)
def test_commands_beyond_the_limits_are_refused_before_anything_is_sent(tmp_path, capsys, limit, message):
    config = write_config(tmp_path, **limit)
    assert main(["run", str(config), "--trials", "2", "--hold", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and __import__("re").search(message, err[0]), err
    assert "refused before sending it to plant process 'python robot.py honest 0'" in err[0]
    assert received(tmp_path) == [] and starts(tmp_path) == []  # the program never even started


GREEDY = """
class Greedy:
    # the nominal solution, then five times it: a step no real car could take

    def __init__(self, context):
        self.c, self.k = context.model.solve(), 0

    def act(self, observation):
        self.k += 1
        return self.c if self.k == 1 else 5 * self.c

    def learn(self, info):
        pass

    def reset(self):
        pass


def make(context):
    return Greedy(context)
"""


def test_a_learner_step_beyond_the_limits_is_refused_and_the_trials_before_it_kept(tmp_path, capsys, monkeypatch):
    config = write_config(tmp_path)
    (tmp_path / "greedy_learner.py").write_text(GREEDY)
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run.json"
    assert main(["run", str(config), "--trials", "3", "--learner", "greedy_learner:make", "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error: plant.limits.workspace: trial 2's nominal path needs" in err[0], err
    assert [t["trial"] for t in json.loads(out.read_text())["trials"]] == [1]
    assert [m.get("trial") for m in received(tmp_path)] == [None, 1]  # trial 2 never left the library


@pytest.mark.parametrize(
    "change, message",
    [
        ({"true_wheelbase": 0.22}, r"plant\.robot: describes a simulated plant other than its nominal model"),
        ({"model": "chained"}, r"plant\.robot"),
    ],
)
def test_the_nested_robot_is_the_nominal_model_only(tmp_path, change, message):
    config = write_config(tmp_path)
    data = yaml.safe_load(config.read_text())
    data["plant"]["robot"].update(change)
    config.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match=message):
        load_config(config)


def test_the_program_runs_in_the_configs_folder_and_python_is_the_librarys(tmp_path, monkeypatch):
    config = write_config(tmp_path)
    monkeypatch.chdir("/")
    plant = load_config(config).plant.plant()
    assert isinstance(plant, ProcessPlant) and plant.folder == str(tmp_path.resolve())
    assert load_config(config).plant.folder == str(tmp_path.resolve())
    assert sys.executable  # "python" in plant.command is this interpreter (robot.py needs nothing else)


def test_the_task_frame_is_the_libraries_the_world_frame_the_programs(tmp_path):
    config = load_config(write_config(tmp_path))
    plant = config.plant.plant().with_frame(0.3)
    q = np.array([1.0, 2.0, 0.4, 0.1])
    assert np.allclose(plant.to_task(plant.to_world(q)), q)
    assert np.allclose(plant.to_world(q)[2], 0.7)


@pytest.mark.slow
@pytest.mark.parametrize("experiment", ["experiment_forward", "experiment_parallel"])
@pytest.mark.parametrize("learner", ["ilc_paper", "robust_ilc"])
def test_section_5s_mario_in_another_process_gives_the_same_trials_bit_for_bit(experiment, learner):
    """The same seeds, the same trial counts and every number of every trial's record."""
    for seed in (1, 2):
        inside = run_ilc(experiment, learner=learner, seed=seed)
        outside = run_ilc(f"{experiment}_process", learner=learner, seed=seed)
        assert outside.converged_at == inside.converged_at
        rows = [{k: v for k, v in t.to_json().items() if k != "plant"} for t in outside.trials]
        assert rows == [t.to_json() for t in inside.trials]


def test_the_plant_and_limit_errors_survive_pickling():
    import pickle

    from ilc_steering.errors import LimitError, PlantError

    for error in (PlantError("plant process 'robot': died"), LimitError("plant.limits.speed: too fast")):
        back = pickle.loads(pickle.dumps(error))
        assert type(back) is type(error) and str(back) == str(error)


class RecordingCable:
    """A cable that records how the answer was judged, without a program."""

    name = "plant process 'fake'"

    def __init__(self):
        self.closed = False

    def fail(self, problem):
        from ilc_steering.errors import PlantError

        self.closed = True
        return PlantError(f"{self.name}: {problem}")

    def close(self, kill=False):
        self.closed = True


JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=True) | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=5), inner, max_size=4),
    max_leaves=12,
)
ANSWERS = st.fixed_dictionaries(
    {"type": st.sampled_from(["result", "error", "hello"]) | JSON, "trial": st.sampled_from([2, 1, 3, "2"]) | JSON},
    optional={
        "final": st.lists(st.floats(-5, 5) | JSON, min_size=0, max_size=6) | JSON,
        "trajectory": JSON,
        "log": JSON,
        "left_chart": JSON,
        "message": JSON,
    },
)


@pytest.fixture(scope="module")
def fake_plant(tmp_path_factory):
    """The fake robot's plant (never started: its answers are judged without it)."""
    return load_config(write_config(tmp_path_factory.mktemp("plant"))).plant.plant()


@settings(max_examples=120, deadline=None)
@given(answer=ANSWERS)
def test_any_answer_is_a_trial_or_one_plant_error(fake_plant, answer):
    """Whatever JSON the program answers trial 2 with, the library either takes a finite pose inside
    the workspace (task frame, in the chart) or raises one PlantError naming the program: nothing else."""
    from ilc_steering.errors import PlantError

    plant = fake_plant
    cable = RecordingCable()
    try:
        q, status, path, log = plant._result(cable, 2, answer, np.zeros(4))
    except PlantError as error:
        assert str(error).startswith("plant process 'fake': ") and "\n" not in str(error) and cable.closed
        return
    assert answer["type"] == "result" and answer["trial"] == 2 and q.shape == (4,) and np.all(np.isfinite(q))
    assert -3 <= q[0] <= 3 and -3 <= q[1] <= 3 and np.all(np.abs(q[2:]) < np.pi / 2) and isinstance(log, dict)
    assert path is None or (path[1].shape == (path[0].size, 4) and np.all(np.diff(path[0]) > 0))


@pytest.mark.parametrize(
    "change, message",
    [
        ({"simulation": {"parameter_jitter": 0.05}}, "an external plant has no true factors to jitter"),
        (
            {
                "task": {
                    "waypoints": [[0.0, 0.0, 0.0, 0.0], [1.0, 0.5, 0.0, 0.0]],
                    "segments": [{"pieces": [5.0], "v1_fixed": [], "v2_terms": 3}],
                }
            },
            r"plant\.model: process runs one-trial tasks",
        ),
    ],
)
def test_what_a_program_cannot_do_is_refused_before_it_starts(tmp_path, change, message):
    from ilc_steering.envs.scenario import Scenario

    config = write_config(tmp_path)
    data = yaml.safe_load(config.read_text()) | change
    config.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match=message):
        Scenario.from_config(load_config(config))
    assert starts(tmp_path) == []


def test_the_lab_robot_refuses_what_it_cannot_serve(capsys):
    """Its own refusals (no simulation runs): a config it does not simulate, another robot, a bad request."""
    import io

    from ilc_steering.lab_robot import LabRobot
    from ilc_steering.lab_robot import main as lab_main

    assert lab_main(["experiment_forward_process"]) == 2
    assert "plant.model process is not a plant the library simulates" in capsys.readouterr().err
    robot, out = LabRobot(load_config("experiment_forward")), io.StringIO()
    hello = {"type": "hello", "protocol": 1, "robot": "unicycle", "dimension": 3}
    robot.serve(io.StringIO(json.dumps(hello) + "\n" + json.dumps({"type": "trial", "trial": 1}) + "\n"), out)
    answers = [json.loads(line) for line in out.getvalue().splitlines()]
    assert answers[0]["type"] == "error" and "the library's robot is 'unicycle'" in answers[0]["message"]
    assert answers[1] == {"type": "error", "trial": 1, "message": "KeyError: 'profile'"}
