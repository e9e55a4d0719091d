"""The engine for grids of cells: killable workers, a bound on every cell, a lock on every run
folder, every failure named on stderr (issue 34, classes 1, 7 and 8)."""

import math
import os
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ilc_steering.engine.backends import run_calls
from ilc_steering.engine.options import DEFAULT_CELL_TIMEOUT, MAX_CELL_TIMEOUT, check_timeout
from ilc_steering.engine.runs import RunFolder

# Calls a worker can run, as (function, args) importable in a spawned process, and what each must give.
KINDS = {
    "returns": ((math.sqrt, (4.0,)), ("done", 2.0)),
    "raises": ((math.sqrt, (-1.0,)), ("failed", "ValueError")),
    "exits": ((os._exit, (7,)), ("failed", "WorkerDied")),
    "hangs": ((time.sleep, (3600.0,)), ("failed", "CallTimeout")),
}


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 10**20), st.booleans()))
def test_a_cell_timeout_is_a_time_up_to_a_week_or_refused_in_one_line(value):
    try:
        bound = check_timeout(value)
    except ValueError as error:
        assert "\n" not in str(error) and "--cell-timeout" in str(error)
        assert value is not None and (
            isinstance(value, bool) or not (math.isfinite(value) and 0 < value <= MAX_CELL_TIMEOUT)
        )
        return
    assert bound is None or 0 < bound <= MAX_CELL_TIMEOUT
    assert DEFAULT_CELL_TIMEOUT <= MAX_CELL_TIMEOUT


def test_1e19_is_refused_by_compare_and_sweep_before_any_cell(tmp_path, capsys):
    from ilc_steering.cli import main

    assert main(["compare", "--cell-timeout", "1e19", "--out", str(tmp_path / "c")]) == 2
    assert main(["sweep", "forward_parking", "--cell-timeout", "1e308", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("--cell-timeout" in line for line in err)
    assert not (tmp_path / "c").exists() and not (tmp_path / "s").exists()


@pytest.mark.slow
@settings(max_examples=4, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.lists(st.sampled_from(sorted(KINDS)), min_size=1, max_size=4), st.integers(1, 2))
def test_a_killable_worker_ends_each_cell_as_returned_failed_died_or_timed_out(kinds, workers):
    """Whatever a call does, it ends as its own outcome and takes no other call with it: a worker
    that dies or outlives the time limit is killed and replaced."""
    calls = {index: KINDS[kind][0] for index, kind in enumerate(kinds)}
    outcomes = {}

    def finish(key, value):
        outcomes[key] = ("done", value)

    def failed(key, message):
        outcomes[key] = ("failed", message.split(":")[0])

    for function in {f for f, _ in calls.values()}:  # run_calls maps one function over its calls
        mine = {k: args for k, (f, args) in calls.items() if f is function}
        run_calls(function, mine, finish, workers=workers, failed=failed, timeout=4.0)
    assert outcomes == {index: KINDS[kind][1] for index, kind in enumerate(kinds)}


def test_a_run_folder_is_locked_for_sweep_too(tmp_path):
    folder = RunFolder(tmp_path, "rows", "sweep")
    folder.prepare({"x": 1}, {})
    with folder.locked(), pytest.raises(ValueError, match="another sweep is running on this folder"):
        with RunFolder(tmp_path, "rows", "sweep").locked():
            pass
    with folder.locked():  # released: a later run takes it
        pass


def test_every_failed_cell_is_named_on_stderr(tmp_path, capsys):
    from ilc_steering.cli import main

    (tmp_path / "raising_learners.py").write_text("def make(context):\n    raise RuntimeError('no learner here')\n")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        argv = ["compare", "--methods", "ilc", "raising_learners:make", "--priors", "nominal", "--seeds", "0"]
        argv += ["--scenarios", "forward_parking", "--model-trials", "3", "--custom-trials", "3", "--workers", "1"]
        assert main([*argv, "--out", str(tmp_path / "run")]) == 4
    finally:
        os.chdir(cwd)
    err = capsys.readouterr().err
    assert "raising_learners:make seed 0: FAILED" in err and "no learner here" in err
    assert "1 of 2 cells failed" in err
    from ilc_steering.engine import provenance as prov

    session = prov.read_run(tmp_path / "run")[1].sessions[-1]  # read back through its schema
    assert session.packages == prov.provenance()["packages"] and session.computed == 1


def _server(behaviour):
    """A local TCP server on a free port that ``behaviour``s each connection: ``silent`` (accepts,
    never answers), ``garbage`` (answers bytes that are no HTTP/2 frame), ``close`` (hangs up)."""
    import socket
    import threading

    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    held = []

    def serve():
        while True:
            try:
                connection, _ = listener.accept()
            except OSError:
                return
            held.append(connection)
            if behaviour == "garbage":
                connection.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n")
            elif behaviour == "close":
                connection.close()

    threading.Thread(target=serve, daemon=True).start()
    return listener, held


@settings(max_examples=6, deadline=None)
@given(st.sampled_from(["silent", "garbage", "close"]), st.sampled_from(["", "ray://"]))
def test_a_port_that_is_no_ray_cluster_is_refused_within_the_promised_time(behaviour, scheme):
    from ilc_steering.engine import backends

    listener, held = _server(behaviour)
    address = f"{scheme}127.0.0.1:{listener.getsockname()[1]}"
    start = time.monotonic()
    try:
        original = backends.RAY_CONNECT_TIMEOUT
        backends.RAY_CONNECT_TIMEOUT = 0.5
        with pytest.raises(ValueError, match="RAY_ADDRESS") as refused:
            backends._check_ray_address(address)
    finally:
        backends.RAY_CONNECT_TIMEOUT = original
        listener.close()
        for connection in held:
            connection.close()
    assert time.monotonic() - start < 0.5 + 1.0 and "\n" not in str(refused.value)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.one_of(st.none(), st.integers(1, 30)), min_size=4, max_size=4),
    st.lists(st.floats(0.0, 1.0), min_size=1, max_size=30),
)
def test_a_cell_whose_trials_to_contradicts_itself_or_its_curve_is_refused(reached, costs):
    """A resumed or committed cell is checked by value: its levels in order, each met where its
    best-so-far curve allows it (both errors within a level: a cost of at most twice it)."""
    from ilc_steering.compare.cells import _contradictions
    from ilc_steering.compare.stats import LADDER

    best = [min(costs[: i + 1]) for i in range(len(costs))]
    curve = [[i + 1, c] for i, c in enumerate(best) if i == 0 or c < best[i - 1]]
    cell = {"trials_to": dict(zip(LADDER, reached)), "curve": curve}
    problems = _contradictions(cell)
    met = [k for k in reached if k is not None]
    ordered = met == reached[: len(met)] and met == sorted(met)
    allowed = all(k is None or best[min(k, len(best)) - 1] <= 2 * t for k, t in zip(reached, LADDER.values()))
    assert (not problems) == (ordered and allowed), (reached, best, problems)


def test_a_report_path_that_is_a_folder_is_refused_before_any_cell(tmp_path, capsys):
    from ilc_steering.cli import main

    (tmp_path / "run" / "compare.json").mkdir(parents=True)
    argv = ["compare", "--methods", "ilc", "--priors", "nominal", "--seeds", "0", "--scenarios", "forward_parking"]
    assert main([*argv, "--model-trials", "2", "--workers", "1", "--out", str(tmp_path / "run")]) == 2
    assert "compare.json: is a folder" in capsys.readouterr().err
    assert not (tmp_path / "run" / "cells").exists()


def test_a_committed_report_holding_a_cell_twice_is_refused(tmp_path):
    import json

    from ilc_steering.compare.committed import read_committed

    (tmp_path / "run.json").write_text(json.dumps({"version": "0.1.0", "configs": {"forward_parking": "x"}}))
    committed = Path(__file__).resolve().parents[1] / "results" / "compare" / "compare.json"
    cell = json.loads(committed.read_text())["cells"][0]  # a whole cell: the schema checks it first
    (tmp_path / "compare.json").write_text(json.dumps({"cells": [cell, {**cell, "best_error": 1.0}]}))
    with pytest.raises(ValueError, match="holds the cell .* twice"):
        read_committed(tmp_path)


@pytest.mark.parametrize("command", [["compare"], ["sweep", "forward_parking"]])
def test_the_help_of_cell_timeout_states_the_engines_default_bound(command, capsys, monkeypatch):
    """``--cell-timeout``'s help reads :data:`DEFAULT_CELL_TIMEOUT` (it once said "no limit" while
    six hours applied): a changed default changes the help."""
    from ilc_steering import cli
    from ilc_steering.engine import options as engine

    for seconds, shown in ((DEFAULT_CELL_TIMEOUT, f"default: {DEFAULT_CELL_TIMEOUT / 3600:g} h"), (5400.0, "1.5 h")):
        monkeypatch.setattr(engine, "DEFAULT_CELL_TIMEOUT", seconds)
        with pytest.raises(SystemExit) as done:
            cli._parser().parse_args([*command, "--help"])
        text = " ".join(capsys.readouterr().out.split())  # argparse wraps at the terminal's width
        option = text.split("--cell-timeout SECONDS ")[-1].split(" --")[0]  # its help, after the usage line
        assert done.value.code == 0 and shown in option and "no limit" not in option, option
