"""Issue 26, results you can trust: one test (or more) per class of bad input, each able to fail."""

from __future__ import annotations

import dataclasses
import json
import os
import stat
import tracemalloc
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ilc_steering  # noqa: F401  (registers the envs)
from ilc_steering.cli import main
from ilc_steering.config import load_config
from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
from ilc_steering.errors import ConfigError
from ilc_steering.readers import MAX_DEPTH, read_json, read_text

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
FORWARD = (CONFIGS / "forward_parking.yaml").read_text()


def _config(tmp_path: Path, old: str, new: str, name: str = "c.yaml") -> Path:
    assert old in FORWARD
    path = tmp_path / name
    path.write_text(FORWARD.replace(old, new))
    return path


# YAML surprises and the one reader


@pytest.mark.parametrize(("text", "reading"), [("010", "8"), ("1:30", "90"), ("-007", "-7")])
def test_yaml_integers_that_yaml_1_1_misreads_are_refused_naming_the_key(tmp_path, text, reading):
    path = _config(tmp_path, "trials: 10 ", f"trials: {text} ")
    message = rf"c\.yaml: learning\.trials: '{text}' is ambiguous: YAML 1\.1 reads it as {reading}"
    with pytest.raises(ConfigError, match=message):
        load_config(path)


def test_a_leading_zero_under_a_string_key_stays_text_and_plain_integers_are_read(tmp_path):
    assert load_config(_config(tmp_path, "name: forward_parking", "name: 010")).name == "010"
    assert load_config(_config(tmp_path, "trials: 10 ", "trials: 12 ")).learning.trials == 12
    assert load_config(_config(tmp_path, "trials: 10 ", "trials: 0x10 ")).learning.trials == 16


def test_a_merge_key_is_honoured_and_an_override_is_no_duplicate(tmp_path):
    tolerance = "  tolerance: {cartesian: 5.0e-4, orientation: 5.0e-4}"
    merged = "  tolerance:\n    <<: {cartesian: 1.0e-3, orientation: 1.0e-3}\n    orientation: 5.0e-4"
    config = load_config(_config(tmp_path, tolerance, merged))
    assert (config.learning.tolerance.cartesian, config.learning.tolerance.orientation) == (1e-3, 5e-4)
    with pytest.raises(ConfigError, match="duplicate key 'orientation'"):
        load_config(_config(tmp_path, tolerance, merged + "\n    orientation: 1.0e-4"))


def test_a_huge_config_is_refused_from_its_size_before_it_is_read(tmp_path):
    path = tmp_path / "huge.yaml"
    with open(path, "wb") as file:
        file.write(FORWARD.encode())
        file.truncate(3 << 30)  # sparse: 3 GB that would cost 3 GB to read
    tracemalloc.start()
    try:
        with pytest.raises(ConfigError, match=r"huge\.yaml: 3221225472 bytes; at most 1048576 bytes are read"):
            load_config(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10 << 20


def test_the_reader_reads_at_most_its_limit_of_a_file_that_grows(tmp_path):
    path = tmp_path / "a.json"
    path.write_text("[" + "1," * 100 + "1]")
    with pytest.raises(ValueError, match=r"a\.json: .* at most 10 bytes"):
        read_text(path, 10)
    assert read_json(path, 1000) == [1] * 101


@pytest.mark.parametrize("depth", [MAX_DEPTH + 1, 20_000])
def test_deep_nesting_is_refused_with_a_message_not_a_recursion_error(tmp_path, depth):
    yaml_path = tmp_path / "deep.yaml"
    yaml_path.write_text("name: " + "[" * depth + "]" * depth + "\n")
    with pytest.raises(ConfigError, match=rf"deep\.yaml: nested deeper than {MAX_DEPTH} levels"):
        load_config(yaml_path)
    json_path = tmp_path / "deep.json"
    json_path.write_text('{"kind": "trials", "x": ' + "[" * depth + "]" * depth + "}")
    assert main(["plot", str(json_path), "--out", str(tmp_path / "p")]) == 2
    with pytest.raises(ValueError, match=rf"deep\.json: nested deeper than {MAX_DEPTH} levels"):
        read_json(json_path, 1 << 30)


def test_a_config_mapping_is_bounded_in_depth_too():
    data: list = []
    for _ in range(MAX_DEPTH + 5):
        data = [data]
    with pytest.raises(ConfigError, match="nested deeper"):
        load_config({"name": data})


def test_run_trials_is_bounded(capsys):
    assert main(["run", "forward_parking", "--trials", "1000000000"]) == 2
    assert "--trials" in capsys.readouterr().err


# One writer for every output


@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_run_json_onto_a_special_file_is_refused_and_the_file_kept(tmp_path, capsys, kind):
    target = tmp_path / "out.json"
    if kind == "fifo":
        os.mkfifo(target)
    else:
        target.mkdir()
    assert main(["run", "forward_parking", "--trials", "1", "--hold", "1", "--json", str(target)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--json" in err and ("regular file" in err or "folder" in err)
    assert (stat.S_ISFIFO if kind == "fifo" else stat.S_ISDIR)(os.lstat(target).st_mode)


def test_the_writer_refuses_a_special_file_it_is_handed(tmp_path):
    from ilc_steering.output import write_atomic, write_json

    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="is a FIFO, not a regular file"):
        write_json(fifo, {})
    link = tmp_path / "link.json"
    (tmp_path / "real.json").write_text("old")
    link.symlink_to(tmp_path / "real.json")
    write_atomic(link, "new")
    assert link.is_symlink() and (tmp_path / "real.json").read_text() == "new"


@pytest.mark.parametrize(("mask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_outputs_keep_the_umask_and_a_replaced_file_its_mode(tmp_path, mask, mode):
    from ilc_steering.output import write_json
    from ilc_steering.tables import write_results

    old = os.umask(mask)
    try:
        write_json(tmp_path / "a.json", {"x": 1})
        write_results([{"a": 1}], tmp_path / "t", "s", "| a |\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / "a.json").st_mode) == mode
    assert {stat.S_IMODE(p.stat().st_mode) for p in (tmp_path / "t").iterdir()} == {mode}
    os.chmod(tmp_path / "a.json", 0o640)
    write_json(tmp_path / "a.json", {"x": 2})
    assert stat.S_IMODE(os.stat(tmp_path / "a.json").st_mode) == 0o640
    assert json.loads((tmp_path / "a.json").read_text()) == {"x": 2}


# Results keyed by content; collisions refused; names injective

TINY = {"priors": ("nominal",), "scenarios": ("forward_parking",), "seeds": (0,), "model_trials": 3, "workers": 1}


def test_a_compare_resumed_with_another_config_of_the_same_name_recomputes_its_cells(tmp_path, capsys):
    """A config's content is part of what made a cell: a resume with another content under the same
    name never takes the old cell, it computes the cell again (the config's cells only)."""
    from ilc_steering.compare.args import Args
    from ilc_steering.compare.command import run_cells

    scenario = tmp_path / "same.yaml"
    scenario.write_text(FORWARD)
    args = Args(out=tmp_path / "run", methods=("ilc",), **{**TINY, "scenarios": (str(scenario),)})
    first = run_cells(args)
    assert first[0]["config_sha"] and len(first) == 1
    assert run_cells(args) == first  # the same content resumes
    scenario.write_text(FORWARD.replace("true_wheelbase: 0.22", "true_wheelbase: 0.3"))
    capsys.readouterr()
    again = run_cells(args)
    assert again[0]["config_sha"] != first[0]["config_sha"] and again[0]["curve"] != first[0]["curve"]
    assert "its config differs" in capsys.readouterr().out
    assert run_cells(args) == again


def test_a_resume_by_another_version_is_refused_saying_so(tmp_path, monkeypatch):
    from ilc_steering.compare import command as compare

    args = compare.Args(out=tmp_path, methods=("ilc",), **TINY)
    compare.run_cells(args)
    monkeypatch.setattr("ilc_steering.compare.settings.__version__", "9.9.9")
    with pytest.raises(ValueError, match=r"version '0\.1\.0', not '9\.9\.9'"):
        compare.run_cells(args)


def test_a_sweep_resumed_with_another_config_of_the_same_name_recomputes_its_rows(tmp_path, capsys):
    from ilc_steering.sweep.command import run_rows
    from ilc_steering.sweep.rows import SweepArgs

    scenario = tmp_path / "same.yaml"
    scenario.write_text(FORWARD)
    args = SweepArgs(config=str(scenario), grid=2, trials=2, workers=1, out=tmp_path / "s")
    first = run_rows(args)
    scenario.write_text(FORWARD.replace("nu_a: 1.0 ", "nu_a: 0.3 "))
    capsys.readouterr()
    again = run_rows(args)
    assert "2 finished results are stale" in capsys.readouterr().out
    (rows,) = again.values()
    assert all(row["config_sha"] != old["config_sha"] for row, old in zip(rows, next(iter(first.values()))))


@pytest.mark.parametrize(("option", "values"), [("--methods", ["ilc", "ilc"]), ("--nu-b", ["1", "1.0"])])
def test_a_sweep_refuses_a_repeated_method_or_gain(tmp_path, capsys, option, values):
    assert main(["sweep", "forward_parking", option, *values, "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert f"{option}: " in err and "given twice" in err and len(err.strip().splitlines()) == 1


def test_file_names_are_injective_in_methods_and_gains(tmp_path):
    from ilc_steering.compare.cells import cell_path
    from ilc_steering.compare.command import METHODS
    from ilc_steering.output import injective_name
    from ilc_steering.sweep.rows import gain_text, row_path

    methods = ["x_y:z", "x:y_z", "x_y_z:w", "newton:ilc", "a b:c", "a_b:c", "pkg.mod:make", "pkg:mod_make", *METHODS]
    names = [injective_name(m, METHODS) for m in methods]
    assert len(set(names)) == len(names)
    assert injective_name("user_learners:make", METHODS) == "user_learners_make"  # readable where it can be
    assert injective_name("newton:ilc", METHODS) != "newton_ilc"  # never a library id's name
    assert len({cell_path(tmp_path, "none", m, "s", 0) for m in methods}) == len(methods)
    gains = [0.1234567, 0.1234568, 1.0, 0.5, 1 / 3]
    assert [gain_text(g) for g in gains[2:4]] == ["1", "0.5"]
    assert len({row_path(tmp_path, "ilc", g, 0) for g in gains}) == len(gains)


def test_users_methods_that_safe_names_would_merge_keep_their_own_cells(tmp_path, monkeypatch):
    from ilc_steering.compare.args import Args
    from ilc_steering.compare.command import run_cells

    (tmp_path / "x_y.py").write_text("from ilc_steering.agents.ilc import make_ilc as z\n")
    (tmp_path / "x.py").write_text("from ilc_steering.agents.ilc import make_ilc_paper as y_z\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    args = Args(out=tmp_path / "run", methods=("x_y:z", "x:y_z"), **{**TINY, "custom_trials": 3, "priors": ("none",)})
    cells = run_cells(args)
    assert [c["method"] for c in cells] == ["x_y:z", "x:y_z"]
    assert cells[0]["curve"] != cells[1]["curve"]  # without a prior, ilc and the paper's ilc start apart
    assert len(list((tmp_path / "run" / "cells").glob("*.json"))) == 2
    assert run_cells(args) == cells  # and the folder resumes


# Resumed data validated


def _one_cell(tmp_path: Path) -> tuple[Any, Path]:
    from ilc_steering.compare.args import Args
    from ilc_steering.compare.command import run_cells

    args = Args(out=tmp_path, methods=("ilc",), **TINY)
    run_cells(args)
    (path,) = (tmp_path / "cells").glob("*.json")
    return args, path


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        ({"best_error": float("nan")}, "best_error nan is not a finite error"),
        ({"wall_s": -1.0}, "wall_s -1.0 is not a time >= 0 s"),
        ({"off_chart_fraction": 7.0}, "off_chart_fraction 7.0 is not a fraction in"),
        ({"trials_to": {"10cm": 999, "1cm": None, "1mm": None, "0.5mm": None}}, "'trials_to' needs"),
        ({"curve": [[1, -1.0]]}, "curve is not increasing in trials with finite errors >= 0"),
        ({"curve": [[99, 1.0]]}, "curve holds a trial outside"),
        ({"fragile": ["2cm"]}, "fragile holds a level"),
    ],
)
def test_a_hand_edited_cell_is_refused_naming_the_file(tmp_path, edit, message):
    from ilc_steering.compare.command import run_cells

    args, path = _one_cell(tmp_path)
    path.write_text(json.dumps({**json.loads(path.read_text()), **edit}))
    with pytest.raises(ValueError, match=message) as error:
        run_cells(args)
    assert path.name in str(error.value)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda row: row["trials_to"].__setitem__(0, 999), "trials_to holds a value outside"),
        (lambda row: row["error"].__setitem__(0, float("nan")), "error holds a value that is not an error"),
        (lambda row: row["left_chart"].__setitem__(0, 7.0), "left_chart holds a value outside"),
        (lambda row: row.__setitem__("wall_s", -5.0), "wall_s -5.0 is not a time"),
        (lambda row: row.__setitem__("row", 1), "holds row 1, not 0"),
    ],
)
def test_a_hand_edited_sweep_row_is_refused_naming_the_file(tmp_path, capsys, edit, message):
    argv = ["sweep", "forward_parking", "--grid", "2", "--trials", "3", "--workers", "1", "--out", str(tmp_path)]
    assert main(argv) == 0
    path = sorted((tmp_path / "rows").glob("*.json"))[0]
    row = json.loads(path.read_text())
    edit(row)
    path.write_text(json.dumps(row))
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and path.name in err and len(err.strip().splitlines()) == 1


# Nothing finished is lost; bounds in time; errors name the culprit

LEARNERS = """
import time

import numpy as np

from ilc_steering.agents.ilc import make_ilc
from ilc_steering.errors import ParameterError


class Failing:
    def __init__(self, context, when):
        self.inner, self.trial, self.when, self.seed = make_ilc(context), 0, when, context.seed

    def act(self, observation):
        self.trial += 1
        self.when(self)
        return self.inner.act(observation)

    def learn(self, info):
        self.inner.learn(info)

    def reset(self):
        self.inner.reset()


def _seed1(self):
    if self.seed == 1:
        raise RuntimeError("seed 1 breaks")


def _svd(self):
    if self.trial == 2:
        raise np.linalg.LinAlgError("SVD did not converge")


def _parameter(self):
    raise ParameterError("my_gain", "must be below 1")


def _forever(self):
    while True:
        time.sleep(0.05)


def seed1(context):
    return Failing(context, _seed1)


def svd(context):
    return Failing(context, _svd)


def parameter(context):
    return Failing(context, _parameter)


def forever(context):
    return Failing(context, _forever)


def broken_factory(context):
    raise KeyError("no such thing")


def exits_in_its_factory(context):
    import sys

    sys.exit(0)


class Weird(BaseException):  # neither an Exception nor an interrupt
    pass


def _weird(self):
    if self.trial == 2:
        raise Weird("weird")


def weird(context):
    return Failing(context, _weird)


class LearnFailsAt2(Failing):
    def __init__(self, context):
        super().__init__(context, lambda self: None)

    def learn(self, info):
        if self.trial == 2:
            raise ValueError("task.pieces: my own value error")
        super().learn(info)


class ActOnly:
    def __init__(self, context):
        pass

    def act(self, observation):
        return None


class NoAct:
    def __init__(self, context):
        pass

    def learn(self, info):
        pass

    def reset(self):
        pass


class NanAt3(Failing):
    def __init__(self, context):
        super().__init__(context, lambda self: None)

    def act(self, observation):
        action = super().act(observation)
        return action * np.nan if self.trial == 3 else action
"""


@pytest.fixture
def learners(tmp_path, monkeypatch):
    (tmp_path / "trust_learners.py").write_text(LEARNERS)
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


@pytest.mark.parametrize("workers", ["1", "2"])
@pytest.mark.slow  # worker processes
def test_a_failing_cell_is_recorded_and_the_others_finish(learners, capsys, workers):
    out = learners / "run"
    argv = ["compare", "--quick", "--out", str(out), "--priors", "nominal", "--scenarios", "forward_parking"]
    argv += ["--methods", "ilc", "trust_learners:seed1", "--seeds", "0", "1", "--custom-trials", "3"]
    assert main([*argv, "--workers", workers]) == 4
    printed = capsys.readouterr()
    assert printed.out.strip().splitlines()[-1].startswith("1 of 4 cells failed")
    assert "bug" not in printed.out + printed.err
    assert len(list((out / "cells").glob("*.json"))) == 3  # every finished cell kept
    (failure,) = (out / "failed").glob("*.json")
    record = json.loads(failure.read_text())
    assert (record["method"], record["seed"], record["prior"], record["scenario"]) == (
        "trust_learners:seed1",
        1,
        "nominal",
        "forward_parking",
    )
    assert "learner trust_learners:seed1: act() raised in trial 1: RuntimeError: seed 1 breaks" in record["error"]
    report = json.loads((out / "compare.json").read_text())
    assert len(report["cells"]) == 3 and report["failed"] == [record]
    assert "1 failed cells" in (out / "compare.md").read_text()


@pytest.mark.parametrize(
    ("method", "message"),
    [
        ("trust_learners:svd", "act() raised in trial 2: LinAlgError: SVD did not converge"),
        ("trust_learners:parameter", "act() raised in trial 1: ParameterError: my_gain: must be below 1"),
        ("trust_learners:broken_factory", "its factory raised KeyError"),
    ],
)
@pytest.mark.slow  # worker processes
def test_a_users_learner_error_crosses_processes_and_names_the_learner_and_the_cell(learners, method, message):
    from ilc_steering.compare.args import Args
    from ilc_steering.compare.command import run_all

    args = Args(out=learners / "run", methods=(method,), **{**TINY, "seeds": (0, 1), "workers": 2})
    cells, failed = run_all(args)
    assert cells == [] and [f["seed"] for f in failed] == [0, 1]
    assert all(message in f["error"] and method in f["error"] for f in failed)


@pytest.mark.slow  # runs out its time limit, which must be far above the ILC cell's time in a fresh worker
def test_a_cell_that_never_returns_is_stopped_by_the_cell_timeout(learners):
    import time

    from ilc_steering.compare.args import Args
    from ilc_steering.compare.command import run_all

    # 2 s once failed here: the ILC cell's fresh worker (numba's cache, the env) took longer under load
    args = Args(out=learners / "run", methods=("ilc", "trust_learners:forever"), cell_timeout=15.0, **TINY)
    start = time.perf_counter()
    cells, failed = run_all(args)
    assert time.perf_counter() - start < 120  # a bound on a hang, not a speed
    assert [c["method"] for c in cells] == ["ilc"]
    assert len(failed) == 1 and "took longer than the time limit of 15 s" in failed[0]["error"]


def test_a_failed_sweep_row_is_recorded_and_its_map_left_out(learners, capsys):
    out = learners / "s"
    argv = ["sweep", "forward_parking", "--methods", "ilc", "trust_learners:svd", "--grid", "2", "--trials", "3"]
    assert main([*argv, "--workers", "1", "--out", str(out)]) == 4
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("2 of 4 rows failed")
    assert len(list((out / "failed").glob("*.json"))) == 2 and len(list((out / "rows").glob("*.json"))) == 2
    assert list(json.loads((out / "sweep.json").read_text())["maps"]) == ["ilc__nu1"]


def test_run_names_the_failing_learner_and_writes_the_trials_it_ran(learners, capsys):
    target = learners / "nan.json"
    assert main(["run", "forward_parking", "--learner", "trust_learners:NanAt3", "--json", str(target)]) == 4
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "learner trust_learners:NanAt3: the env refused its action in trial 3" in err
    assert "bug" not in err
    assert [t["trial"] for t in json.loads(target.read_text())["trials"]] == [1, 2]


def test_a_learner_that_fails_in_learn_keeps_the_trial_it_ran(learners, capsys):
    """Trial 2 ran before learn() failed on it: it is printed and written (before: neither)."""
    target = learners / "learn.json"
    argv = ["run", "forward_parking", "--learner", "trust_learners:LearnFailsAt2", "--json", str(target)]
    assert main(argv) == 4
    printed = capsys.readouterr()
    assert "learner trust_learners:LearnFailsAt2: learn() raised in trial 2: ValueError" in printed.err
    assert [line.split()[0] for line in printed.out.splitlines() if line.startswith("    ")] == ["1", "2"]
    assert [t["trial"] for t in json.loads(target.read_text())["trials"]] == [1, 2]


@pytest.mark.parametrize(
    ("learner", "code", "message"),
    [
        ("trust_learners:exits_in_its_factory", 4, "learner trust_learners:exits_in_its_factory: its factory raised "
         "SystemExit: 0"),  # before: exit 0, nothing said
        ("sys:exit", 4, "learner sys:exit: its factory raised SystemExit: LearnerContext("),  # before: exit 1
        ("trust_learners:weird", 4, "learner trust_learners:weird: act() raised in trial 2: Weird: weird"),
        ("trust_learners:NoAct", 2, "made NoAct, which has no act method"),  # before: "no act, learn and reset"
        ("trust_learners:ActOnly", 2, "made ActOnly, which has no learn and reset method"),
    ],
)  # fmt: skip
def test_a_learner_that_exits_raises_anything_or_lacks_a_method_is_named(learners, capsys, learner, code, message):
    assert main(["run", "forward_parking", "--trials", "3", "--learner", learner]) == code
    err = capsys.readouterr().err
    assert message in err and len(err.splitlines()) == 1 and len(err) < 500 and "bug" not in err


def test_workers_are_capped(tmp_path, capsys):
    from ilc_steering.engine.backends import MAX_WORKERS

    for command in (["compare", "--methods", "ilc"], ["sweep", "forward_parking"]):
        argv = [*command, "--workers", str(MAX_WORKERS + 1), "--out", str(tmp_path / command[0])]
        assert main(argv) == 2
        assert f"--workers: a whole number in [0, {MAX_WORKERS}]" in capsys.readouterr().err


def test_an_unreachable_ray_address_is_refused_quickly(monkeypatch):
    # (an address that answers but is no Ray is bounded by a time limit on ray.init: bad_inputs replays it)
    import time

    from ilc_steering.engine import backends

    monkeypatch.setattr(backends, "RAY_CONNECT_TIMEOUT", 1.0)
    start = time.perf_counter()
    with pytest.raises(ValueError, match=r"RAY_ADDRESS 127\.0\.0\.1:1: no Ray cluster answers there within 1 s"):
        backends._check_ray_address("127.0.0.1:1")  # nothing listens on port 1
    assert time.perf_counter() - start < 5
    with pytest.raises(ValueError, match="give host:port"):
        backends._check_ray_address("nonsense")
    backends._check_ray_address("auto")  # nothing to reach: ray.init finds it


def test_exit_codes_are_documented():
    from ilc_steering.cli import EXIT_CODES, _parser

    assert sorted(EXIT_CODES) == [0, 1, 2, 3, 4, 5, 130]
    assert "5 converged to the plant's floor" in (_parser().epilog or "")
    assert "4 the user's code failed (a learner, or a plant" in (_parser().epilog or "")


def test_the_librarys_errors_survive_pickling():
    import pickle

    import ilc_steering.engine.backends  # noqa: F401  (registers ParameterError's reduction)
    from ilc_steering.errors import LearnerError, ParameterError

    for error in (ParameterError("nu_b", "must be in (0, 2)"), ConfigError("a.yaml: x: y"), LearnerError("learner z")):
        back = pickle.loads(pickle.dumps(error))
        assert type(back) is type(error) and str(back) == str(error)
    assert pickle.loads(pickle.dumps(ParameterError("nu_b", "bad"))).problem == "bad"


# The property suite: derandomized in CI, extended to sweep's and compare's arguments


def test_the_property_suite_is_derandomized_in_ci():
    import subprocess
    import sys

    code = "import tests.conftest, hypothesis; print(hypothesis.settings.default.derandomize)"
    root = Path(__file__).resolve().parents[1]
    local = {k: v for k, v in os.environ.items() if k not in ("CI", "GITHUB_ACTIONS", "TF_BUILD")}
    for env, expected in (({**local, "CI": "true"}, "True"), (local, "False")):
        result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=root)
        assert result.stdout.strip() == expected, result.stderr


from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

gains = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.5, 1.0, 2.0, 0.0, -1.0]))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    methods=st.lists(st.sampled_from(["ilc", "ilc_paper", "newton", "ppo", "nope", "x:y"]), max_size=3),
    nu_b=st.lists(gains, max_size=3),
    grid=st.one_of(st.integers(-5, 300), st.booleans()),
    trials=st.integers(-5, 200_000),
    workers=st.integers(-3, 1000),
    timeout=st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True)),
)
def test_sweep_arguments_are_accepted_or_refused_with_a_value_error(methods, nu_b, grid, trials, workers, timeout):
    from ilc_steering.engine.backends import MAX_WORKERS
    from ilc_steering.engine.options import MAX_CELL_TIMEOUT
    from ilc_steering.sweep.command import plan
    from ilc_steering.sweep.rows import SweepArgs

    args = SweepArgs(
        methods=tuple(methods), nu_b=tuple(nu_b), grid=grid, trials=trials, workers=workers, cell_timeout=timeout
    )
    try:
        plan(args)
    except ValueError as error:
        assert str(error) and "\n" not in str(error)
        return
    assert len(set(methods)) == len(methods) > 0 and len(set(nu_b)) == len(nu_b)
    assert all(0 < g <= 2 for g in nu_b) and 2 <= grid <= 201 and 0 <= workers <= MAX_WORKERS
    assert timeout is None or 0 < timeout <= MAX_CELL_TIMEOUT


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    methods=st.lists(st.sampled_from(["ilc", "newton", "least_squares", "nope"]), max_size=3),
    seeds=st.lists(st.integers(-2, 2**33), max_size=3),
    budget=st.integers(-2, 2_000_000),
    workers=st.integers(-3, 1000),
    timeout=st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True)),
)
def test_compare_arguments_are_accepted_or_refused_with_a_value_error(methods, seeds, budget, workers, timeout):
    from ilc_steering.compare.args import MAX_BUDGET, Args
    from ilc_steering.compare.command import validate
    from ilc_steering.engine.options import MAX_CELL_TIMEOUT

    args = Args(
        methods=tuple(methods),
        scenarios=("forward_parking",),
        seeds=tuple(seeds),
        model_trials=budget,
        workers=workers,
        cell_timeout=timeout,
    )
    try:
        validate(args)
    except ValueError as error:
        assert str(error) and "\n" not in str(error)
        return
    assert len(set(methods)) == len(methods) > 0 and len(set(seeds)) == len(seeds) > 0
    assert 1 <= budget <= MAX_BUDGET and all(0 <= s < 2**32 for s in seeds)
    assert timeout is None or 0 < timeout <= MAX_CELL_TIMEOUT  # 1e19 is refused, not an OverflowError later


# Ill-posed tasks found before any trial

CHAINED = (CONFIGS / "chained_perturbed.yaml").read_text()


def _mirrored(tmp_path: Path) -> Path:
    # v1 = 0.5 on piece 1 and -0.5 on piece 2 (the goal shares z1): W of eq. 23 is singular there
    text = CHAINED.replace("goal:  [1.0,", "goal:  [0.0,").replace("v1_fixed: [0.5]", "v1_fixed: [-0.5]")
    assert text != CHAINED
    path = tmp_path / "mirrored.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("command", ["run", "compare", "sweep"])
def test_an_ill_posed_task_is_refused_before_any_trial_naming_what_to_change(tmp_path, capsys, command):
    path = _mirrored(tmp_path)
    argv = {
        "run": ["run", str(path)],
        "compare": ["compare", "--scenarios", str(path), "--methods", "ilc", "--out", str(tmp_path / "c")],
        "sweep": ["sweep", str(path), "--out", str(tmp_path / "s")],
    }[command]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "an ill-posed task" in err and "task.v1_fixed" in err
    assert "misses the goal by 0.78 of the distance" in err
    assert not (tmp_path / "c" / "cells").exists() or not any((tmp_path / "c" / "cells").iterdir())


@pytest.mark.extra("highway")  # highway_parking is packaged
def test_every_packaged_one_trial_task_is_well_posed():
    import gymnasium as gym

    from ilc_steering.config import packaged_configs
    from ilc_steering.runner import ENV_ID, check_task, step_warning

    checked = 0
    for name in packaged_configs():
        config = load_config(name)
        if not config.is_cyclic and not config.is_segmented:  # a manoeuvre's segments: tests/test_segmented.py
            check_task(gym.make(ENV_ID, config=config), name)
            assert step_warning(config) is None, name  # and its step is fine enough
            checked += 1
    assert checked >= 9


def test_a_coarse_integrator_step_is_found_by_halving_it(tmp_path, capsys):
    from ilc_steering.runner import step_warning

    assert step_warning(load_config("forward_parking")) is None  # 1/32 s: within 1e-12 of half of it
    path = tmp_path / "coarse.yaml"
    path.write_text(FORWARD + "simulation: {max_step: 1.0}\n")
    warning = step_warning(load_config(path))
    assert warning is not None and "simulation.max_step = 1 s is too coarse" in warning
    assert main(["run", str(path), "--trials", "1", "--hold", "1"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "lower simulation.max_step" in err


def test_clipped_actions_are_reported_by_run_and_compare(tmp_path, capsys):
    from ilc_steering.compare.args import Args
    from ilc_steering.compare.command import run_cells

    # a box just around the nominal solution's c2 (-12, 14.4, -2.88): every learned update leaves it
    boxed = tmp_path / "boxed.yaml"
    bound = "v2_terms: 3\n  action_bound: [1.0, 12.000001, 14.400001, 2.880001] "
    boxed.write_text(FORWARD.replace("v2_terms: 3 ", bound))
    cells = run_cells(Args(out=tmp_path / "c", methods=("ilc",), **{**TINY, "scenarios": (str(boxed),)}))
    assert cells[0]["clipped_fraction"] == pytest.approx(2 / 3)  # all but the first of 3 trials
    capsys.readouterr()
    assert main(["run", str(boxed), "--trials", "4"]) == 1
    out = capsys.readouterr().out
    assert out.count("action clipped to the box") == 3 and "3 of 4 actions were clipped" in out
    assert main(["run", "forward_parking", "--trials", "2", "--hold", "2"]) == 1
    assert "clipped" not in capsys.readouterr().out


@pytest.mark.slow  # fresh processes
def test_a_users_learner_in_the_working_directory_is_found_by_the_installed_script(tmp_path):
    import subprocess
    import sys

    (tmp_path / "here_learners.py").write_text("from ilc_steering.agents.ilc import make_ilc as make\n")
    script = Path(sys.executable).with_name("ilc-steering")
    run = [str(script), "run", "forward_parking", "--learner", "here_learners:make", "--trials", "6"]
    result = subprocess.run(run, capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert result.returncode == 0 and "converged at trial" in result.stdout, result.stderr
    compare = [str(script), "compare", "--methods", "here_learners:make", "--priors", "nominal", "--seeds", "0"]
    compare += ["--scenarios", "forward_parking", "--custom-trials", "3", "--workers", "1", "--out", "c"]
    result = subprocess.run(compare, capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert result.returncode == 0 and "all 1 cells finished" in result.stdout, result.stderr


# Options and numerics the envs and the chained plant took without a word (issue 26).
@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: gym.make("ilc_steering/ChainedSteering-v0", record_trajectory="no"), "record_trajectory must be"),
        (lambda: gym.make("ilc_steering/CyclicSteering-v0", record_trajectory=1), "record_trajectory must be"),
        (lambda: ChainedSteeringVectorEnv(2, parallel="yes"), "parallel must be True, False or None"),
    ],
)
def test_an_option_that_is_not_a_flag_is_refused(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_the_one_trial_env_refuses_reset_options_it_would_ignore():
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking")
    with pytest.raises(ValueError, match=r"options: the one-trial env takes none, got \['start'\]"):
        env.reset(seed=0, options={"start": [0.1, 0.0, 0.0, 0.0]})
    env.reset(seed=0, options={})  # an empty mapping asks for nothing


def test_chained_gains_are_bounded():
    data = dataclasses.asdict(load_config("chained_perturbed"))
    data["plant"]["v2_gain"] = 5.2e154  # the property suite's find: z overflowed to inf
    with pytest.raises(ConfigError, match=r"plant\.v2_gain: must be nonzero and within \+-1000"):
        load_config(data)


def test_start_draws_outside_the_chart_are_drawn_again_never_folded():
    """A start drawn past the steering limit (or |theta| >= pi/2) would reach the kernel folded by pi;
    every trial's start stays inside, and a sigma beyond a homing error (MAX_START_ERROR) is refused."""
    env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking_saturated", start_error=0.5)
    env.reset(seed=0)
    scenario = env.unwrapped._scenario
    rng = np.random.default_rng(0)
    for _ in range(200):
        x0, _ = scenario.draw_disturbance(rng)
        scenario.plant.check_configuration(scenario.plant.configuration(x0))  # raises if outside
    with pytest.raises(ValueError, match=r"start_error: each sigma must be finite and in \[0, 1\]"):
        gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking_saturated", start_error=1e3)  # issue 34
