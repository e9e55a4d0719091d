"""Bad input, class by class: each test reproduces defects that once ended in a traceback, a hang,
a silently wrong number or a lost result, and checks the clear error that replaced them."""

import json
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.cli import main
from ilc_steering.compare import command as compare
from ilc_steering.compare import settings as compare_settings
from ilc_steering.compare.args import Args
from ilc_steering.compare.cells import run_cell
from ilc_steering.compare.command import run_cells
from ilc_steering.config import load_config
from ilc_steering.errors import ConfigError
from ilc_steering.output import safe_name, write_json

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
FORWARD = yaml.safe_load((CONFIGS / "forward_parking.yaml").read_text())


def config_file(tmp_path, filename="task.yaml", **changes):
    """The forward-parking config with ``changes`` (``section__key=value``) written to ``tmp_path``."""
    data = json.loads(json.dumps(FORWARD))
    for dotted, value in changes.items():
        *parents, key = dotted.split("__")
        node = data
        for parent in parents:
            node = node[parent]
        node[key] = value
    path = tmp_path / filename
    path.write_text(yaml.safe_dump(data))
    return path


def one_line_error(capsys):
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    return err


# --- the CLI contract: 0 converged, 1 not, 2 bad input (before any trial), 3 internal error


def test_malformed_yaml_exits_2_naming_the_file_and_line(tmp_path, capsys):
    path = tmp_path / "broken.yaml"
    path.write_text("name: [\n")
    assert main(["run", str(path)]) == 2
    err = one_line_error(capsys)
    assert "broken.yaml" in err and "not valid YAML at line 2" in err


@pytest.mark.parametrize("content", [b"name: \xff\xfe\n", b"\x00" * 10])
def test_undecodable_config_exits_2_naming_the_file(tmp_path, capsys, content):
    path = tmp_path / "binary.yaml"
    path.write_bytes(content)
    assert main(["run", str(path)]) in (2,)
    assert "binary.yaml" in one_line_error(capsys)


def test_an_unwritable_output_is_refused_before_any_trial(tmp_path, capsys):
    assert main(["run", "forward_parking", "--json", "/proc/x/a.json"]) == 2
    assert "--json" in one_line_error(capsys)
    assert "trial" not in capsys.readouterr().out  # nothing ran
    folder = tmp_path / "a-folder"
    folder.mkdir()
    assert main(["run", "forward_parking", "--json", str(folder)]) == 2
    assert "is a folder" in one_line_error(capsys)
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["run", "forward_parking", "--plots", str(blocker / "figures")]) == 2
    assert main(["reproduce", "--json-dir", str(blocker)]) == 2


def test_an_internal_error_exits_3_with_one_line_and_a_traceback_only_with_debug(monkeypatch, capsys):
    from ilc_steering import cli

    def broken(*args, **kwargs):
        raise ZeroDivisionError("boom")

    monkeypatch.setattr(cli, "learn", broken)
    assert main(["run", "forward_parking"]) == 3
    err = one_line_error(capsys)
    assert "internal error: ZeroDivisionError: boom" in err and "report" in err
    assert main(["--debug", "run", "forward_parking"]) == 3
    assert "Traceback" in capsys.readouterr().err


def test_bad_arguments_exit_2(capsys):
    assert main(["run", "forward_parking", "--trials", "0"]) == 2
    with pytest.raises(SystemExit) as exit_:
        main(["run", "forward_parking", "--trials", "many"])
    assert exit_.value.code == 2


def test_plot_on_malformed_records_names_the_file_and_the_record(tmp_path, capsys):
    run = tmp_path / "run.json"
    assert main(["run", "forward_parking", "--trials", "2", "--hold", "2", "--json", str(run)]) == 1
    data = json.loads(run.read_text())
    for broken in (
        {**data, "trials": [{"trial": 1}]},
        {**data, "trials": [{**data["trials"][0], "final_state": [1.0]}]},
        {**data, "config": "forward_parking"},  # a run file may not point at another file
        [1, 2],
    ):
        run.write_text(json.dumps(broken))
        assert main(["plot", str(run), "--out", str(tmp_path / "figures")]) == 2
        assert "run.json" in one_line_error(capsys)
    run.write_text("{")
    assert main(["plot", str(run), "--out", str(tmp_path / "figures")]) == 2
    assert "not valid JSON" in one_line_error(capsys)


# --- files are written only inside the folder the user named


@pytest.mark.parametrize("name", ["/tmp/x", "../../y", "", "a\x00b", ".hidden", "a b"])
def test_config_names_that_would_write_elsewhere_are_refused(tmp_path, name):
    with pytest.raises(ConfigError, match="name: must be"):
        load_config(config_file(tmp_path, name=name))


def test_safe_names_stay_in_the_folder():
    for name in ("../../y", "/tmp/x", "", "..", "a/b\\c"):
        cleaned = safe_name(name)
        assert cleaned and "/" not in cleaned and not cleaned.startswith(".")


def test_atomic_writes_use_unique_temporary_files(tmp_path):
    target = tmp_path / "cell.json"
    write_json(target, {"a": 1})
    write_json(target, {"a": 2})
    assert json.loads(target.read_text()) == {"a": 2}
    assert [p.name for p in tmp_path.iterdir()] == ["cell.json"]


# --- bounded work


def test_a_yaml_alias_bomb_is_refused_quickly(tmp_path):
    lines = ["a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    for previous, name in zip("abcdefgh", "bcdefghi"):
        lines.append(f"{name}: &{name} [" + ", ".join([f"*{previous}"] * 9) + "]")
    path = tmp_path / "bomb.yaml"
    path.write_text("\n".join(lines) + "\n")
    code = f"from ilc_steering.config import load_config\nload_config({str(path)!r})"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and "more than 100000 values" in done.stderr


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"simulation": {"max_step": 1.0e-9}}, r"simulation\.max_step: .*at most 200000"),
        ({"task__pieces": [1.0e9]}, r"task\.pieces: durations must be in \[0\.001, 10000\] s"),
        ({"task__pieces": [1.0e20]}, r"task\.pieces: durations must be in \[0\.001, 10000\] s"),
        ({"task__pieces": [1.0e300]}, r"task\.pieces: durations must be in"),
        ({"task__v2_terms": 200}, r"v2_terms: needs 1 <= q <= 12"),
        ({"task__start": [-1.0e300, 0.0, 0.785, 0.0]}, r"task\.start: .*within"),
        ({"task__start": [-1.0e38, 0.0, 0.785, 0.0]}, r"task\.start: .*within"),
        ({"task__action_bound": [1.0e39, 1.0, 1.0, 1.0]}, r"action_bound: .*float32"),
    ],
)
def test_configs_asking_for_unbounded_work_are_refused(tmp_path, changes, message):
    with pytest.raises(ConfigError, match=message):
        load_config(config_file(tmp_path, **changes))


def test_a_trial_that_leaves_the_chart_says_so_in_the_table(tmp_path, capsys):
    path = config_file(tmp_path, simulation={"max_step": 5.0})
    assert main(["run", str(path), "--trials", "1", "--hold", "1"]) == 1
    assert "left the chart" in capsys.readouterr().out


# --- the shared-z1 rule is checked in the task frame


def test_shared_z1_is_judged_in_the_rotated_task_frame(tmp_path):
    # frame = 2.0 rad: the goal's x in the task frame is cos(2) + 0.4577 sin(2), 4e-5 m from the start's
    rotated = {"task__start": [0.0, 0.0, 2.0, 0.0], "task__goal": [1.0, 0.4577, 2.0, 0.0]}
    with pytest.raises(ConfigError, match="share z1"):
        load_config(config_file(tmp_path, **rotated))
    exact = {**rotated, "task__goal": [1.0, float(-1 / np.tan(2.0)), 2.0, 0.0]}
    with pytest.raises(ConfigError, match="share z1"):
        load_config(config_file(tmp_path, **exact))
    feasible = {"task__start": [0.0, 0.0, 2.0, 0.0], "task__goal": [0.0, -1.0, 2.0, 0.0]}
    assert load_config(config_file(tmp_path, **feasible)).frame() == pytest.approx(2.0)
    with pytest.raises(ConfigError, match="share z1"):
        load_config(config_file(tmp_path, task__goal=[-1.0 + 1e-12, 0.0, 0.785, 0.0]))


# --- compare: validated before the first cell, duplicates refused, resumed cells checked


def test_compare_refuses_bad_arguments_before_any_cell(tmp_path, capsys):
    for argv in (
        ["--seeds", "0", "0"],
        ["--methods", "ilc", "ilc"],
        ["--scenarios", "forward_parking", "forward_parking"],
        ["--seeds", "-1"],
        ["--scenarios", "cyclic_home_goal"],
        ["--scenarios", "forward_parking", "no_such_scenario"],
        ["--methods", "ilc", "nope"],
        ["--priors", "nominal", "nominal"],
        ["--priors", "optimistic"],
        ["--methods", "no_such_module:make"],
        ["--workers", "-1"],
        ["--rl-trials", "0"],
    ):
        out = tmp_path / "run"
        assert main(["compare", "--quick", "--out", str(out), *argv]) == 2, argv
        one_line_error(capsys)
        assert not (out / "cells").exists() or not list((out / "cells").iterdir()), argv


def test_quick_keeps_explicit_seeds_and_budgets():
    assert compare_settings.resolve(compare.parse(["--quick", "--seeds", "3"])).seeds == (3,)
    assert compare_settings.resolve(compare.parse(["--quick"])).seeds == (0, 1)
    assert compare_settings.resolve(compare.parse(["--quick", "--model-trials", "9"])).model_trials == 9


@pytest.mark.slow  # a comparison
def test_compare_runs_chained_plants_and_yaml_paths(tmp_path):
    path = CONFIGS / "parallel_parking.yaml"
    args = Args(
        out=tmp_path,
        priors=("nominal",),
        methods=("ilc_paper",),
        scenarios=("chained_perturbed", str(path)),
        seeds=(0,),
        model_trials=8,
    )
    cells = run_cells(args)
    assert [c["scenario"] for c in cells] == ["chained_perturbed", "parallel_parking"]
    assert cells[0]["trials_to"]["0.5mm"] is not None and cells[1]["trials_to"]["0.5mm"] == 5


@pytest.mark.slow  # comparisons
def test_resumed_cells_are_checked_against_their_key(tmp_path):
    args = Args(
        out=tmp_path,
        priors=("nominal",),
        methods=("ilc",),
        scenarios=("forward_parking",),
        seeds=(0, 1),
        model_trials=4,
    )
    run_cells(args)
    cells = tmp_path / "cells"
    first, second = cells / "nominal__ilc__forward_parking__0.json", cells / "nominal__ilc__forward_parking__1.json"
    original = first.read_text()
    for broken, message in (
        (original[:-5], "not a readable cell"),
        ("", "not a readable cell"),
        ("[1, 2]", "not a cell"),
        (json.dumps({**json.loads(original), "trials": "4"}), "trials: must be an integer, got '4'"),
        (second.read_text(), "holds seed 1, not 0"),
        (json.dumps({**json.loads(original), "trials_to": {"1cm": 2}}), "'trials_to' needs"),
    ):
        first.write_text(broken)
        with pytest.raises(ValueError, match=message) as error:
            run_cells(args)
        assert "nominal__ilc__forward_parking__0.json" in str(error.value)
    first.write_text(original)
    (tmp_path / "run.json").unlink()
    with pytest.raises(ValueError, match="no run.json"):
        run_cells(args)


def test_a_file_where_the_cells_folder_should_be(tmp_path):
    (tmp_path / "cells").write_text("")
    with pytest.raises(ValueError, match="not a folder"):
        run_cells(Args(out=tmp_path, methods=("ilc",), scenarios=("forward_parking",), seeds=(0,)))


def test_two_compares_cannot_share_a_folder(tmp_path):
    import fcntl

    tmp_path.mkdir(exist_ok=True)
    with open(tmp_path / ".lock", "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        with pytest.raises(ValueError, match="another compare is running"):
            run_cells(Args(out=tmp_path, methods=("ilc",), scenarios=("forward_parking",), seeds=(0,), model_trials=3))


def test_a_cell_of_a_chained_plant_counts_the_error_norm():
    cell = run_cell(Args(model_trials=10), "nominal", "ilc_paper", "chained_perturbed", 0)
    assert cell["trials_to"]["0.5mm"] == 5 and cell["off_chart_fraction"] == 0.0


# --- actions and envs


@pytest.mark.parametrize(
    "action",
    [
        np.array([1 + 1j, 0, 0, 0]),
        ["1", "2", "3", "4"],
        np.array(["2020-01-01"] * 4, dtype="datetime64[D]"),
        np.ma.array([1.0, 2, 3, 4], mask=[0, 1, 0, 0]),
        [10**400, 0, 0, 0],
        [True, False, True, False],
        [[1.0], [1.0, 2.0]],
    ],
)
def test_non_real_actions_raise_value_error(action):
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(action)


def test_the_vector_env_does_not_advertise_rendering_and_checks_its_arguments():
    with pytest.raises(ValueError, match="render_mode"):
        gym.make_vec(
            "ilc_steering/ChainedSteering-v0", 2, vectorization_mode="vector_entry_point", render_mode="rgb_array"
        )
    with pytest.raises(ValueError, match="num_envs"):
        gym.make_vec("ilc_steering/ChainedSteering-v0", True, vectorization_mode="vector_entry_point")
    envs = gym.make_vec("ilc_steering/ChainedSteering-v0", 4, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="one seed per env"):
        envs.reset(seed=[1])
    envs.reset(seed=[1, 2, 3, 4])


def test_the_one_trial_env_refuses_a_cyclic_config():
    with pytest.raises(ValueError, match="CyclicSteering-v0"):
        gym.make("ilc_steering/ChainedSteering-v0", config="cyclic_home_goal")


@pytest.mark.parametrize(
    "options, message",
    [
        ({"strt": [0, 0, 0, 0]}, "unknown key 'strt'"),
        ([1], "must be a dict"),
        ({"start": [0, 0, 1.5703, 0]}, "inside pi/2"),
    ],
)
def test_cyclic_reset_options_are_checked(options, message):
    env = gym.make("ilc_steering/CyclicSteering-v0", config="cyclic_home_goal")
    with pytest.raises(ValueError, match=message):
        env.reset(options=options)


@pytest.mark.parametrize("cycles", ["3", 0, True, 2.5])
def test_cyclic_cycles_must_be_a_whole_number(cycles):
    with pytest.raises(ValueError, match="cycles"):
        gym.make("ilc_steering/CyclicSteering-v0", config="cyclic_home_goal", cycles=cycles)


def test_config_none_is_a_clear_error():
    with pytest.raises(ValueError, match="config must be"):
        gym.make("ilc_steering/ChainedSteering-v0", config=None)


# --- config messages


def test_duplicate_yaml_keys_are_refused(tmp_path):
    path = tmp_path / "twice.yaml"
    path.write_text((CONFIGS / "forward_parking.yaml").read_text() + "\nname: again\n")
    with pytest.raises(ConfigError, match="twice.yaml: duplicate key 'name'"):
        load_config(path)


def test_exponent_numbers_read_as_numbers(tmp_path):
    path = config_file(tmp_path)
    path.write_text(path.read_text().replace("cartesian: 0.0005", "cartesian: 1e-3"))
    assert load_config(path).learning.tolerance.cartesian == 1e-3


def test_a_car_tolerance_with_an_error_key_is_refused(tmp_path):
    tolerance = {"cartesian": 5e-4, "orientation": 5e-4, "error": 1e-3}
    with pytest.raises(ConfigError, match="learning.tolerance: a car needs"):
        load_config(config_file(tmp_path, learning__tolerance=tolerance))


def test_cyclic_action_bound_and_mixed_terms_are_config_errors(tmp_path):
    data = yaml.safe_load((CONFIGS / "cyclic_home_goal.yaml").read_text())
    data["task"]["action_bound"] = [1.0, 1.0]
    path = tmp_path / "cyclic.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"cyclic.yaml: task\.action_bound: needs 1 \+ v2_terms = 4 values"):
        load_config(path)
    data["task"]["action_bound"] = None
    segment = data["task"]["segments"][0]
    data["task"]["segments"] = [segment, {**segment, "v2_terms": 4}]
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"the same v2_terms .*\[3, 4\]"):
        load_config(path)
