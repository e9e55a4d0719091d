"""Bad inputs, replayed: issues 12's and 26's defect lines against an installed ilc-steering, each outcome classified.

Each attack runs in a fresh interpreter (``--python``, default: this one) with a 60 s limit and
is classified as ``clear`` (a one-line error that names the file, key or option, exit 2, or a
``ValueError``; or, for the few valid inputs once refused, a normal run; for issue 26's
multi-step attacks, the check the attack states: a recorded failure and exit 4, a recomputed or
refused resume, ...), ``warned`` (run, with a one-line warning that names the key; counted as
clear), ``traceback``, ``hang`` (no bound in time), ``blow-up`` (peak memory above the attack's
bound, :data:`MEMORY_BOUND`), ``silent`` (bad input taken without a word, a wrong result, a
result lost), ``unclear`` (an error that names no file), ``late`` (found after work was done) or
``refused a valid input``. Point ``--python`` at another install (an older version in its own
virtual environment, or a source tree on ``PYTHONPATH``) to compare: ``results/bad_inputs/before``
holds the run against the commit before issue 26's changes (373f0ec), ``results/bad_inputs`` the
run after.

    python benchmarks/bad_inputs.py [--quick] [--python PY] [--out DIR]
"""

from __future__ import annotations

import collections
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ilc_steering.arguments import Parser
from ilc_steering.config import load_config
from ilc_steering.engine.provenance import record_made
from ilc_steering.tables import markdown_table, write_results

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
FORWARD_CONFIG = dataclasses.asdict(load_config("forward_parking"))


@dataclass(frozen=True)
class Args:
    quick: bool = False
    """Only the first attack of each class (CI)."""
    python: str = sys.executable
    """The interpreter whose ilc_steering is attacked."""
    out: Path = Path("results/bad_inputs")
    """Folder for the JSON, CSV and Markdown results."""


def attacks(tmp: str) -> list[tuple[str, str, str, Any]]:
    """(class, description, "py" or "cli", code or argv) of every attack, files written to ``tmp``."""
    FWD = (CONFIGS / "forward_parking.yaml").read_text()

    def cfg(name: str, replace: list[tuple[str, str]] | None = None, append: str = "") -> str:
        text = FWD
        for a, b in replace or []:
            assert a in text, a
            text = text.replace(a, b)
        path = os.path.join(tmp, name)
        Path(path).write_text(text + append)
        return path

    attacks: list[tuple[str, str, str, Any]] = []

    def py(cls: str, desc: str, code: str) -> None:
        attacks.append((cls, desc, "py", PRE + textwrap.dedent(code)))

    def cli(cls: str, desc: str, *argv: str) -> None:
        attacks.append((cls, desc, "cli", list(argv)))

    # CLI contract
    bad = os.path.join(tmp, "bad.yaml")
    open(bad, "w").write("name: [\n")
    cli("cli", "malformed YAML", "run", bad)
    cli("cli", "unwritable --json", "run", "forward_parking", "--json", "/proc/x/a.json")
    u = os.path.join(tmp, "latin.yaml")
    open(u, "wb").write(b"name: \xff\xfe\n")
    cli("cli", "non-UTF-8 config", "run", u)
    j = os.path.join(tmp, "broken.json")
    open(j, "w").write("{")
    cli("cli", "truncated run JSON to plot", "plot", j, "--out", os.path.join(tmp, "p1"))
    j2 = os.path.join(tmp, "records.json")
    open(j2, "w").write(json.dumps({"kind": "trials", "trials": [{"trial": 1}], "config": FORWARD_CONFIG}))
    cli("cli", "plot on malformed records", "plot", j2, "--out", os.path.join(tmp, "p2"))
    # Writes outside the output folder
    cli(
        "paths",
        "name /tmp/x",
        "run",
        cfg("n1.yaml", [("name: forward_parking", "name: /tmp/attack_x")]),
        "--trials",
        "1",
        "--plots",
        os.path.join(tmp, "f1"),
    )
    cli(
        "paths",
        "name ../../y",
        "run",
        cfg("n2.yaml", [("name: forward_parking", "name: ../../attack_y")]),
        "--trials",
        "1",
        "--plots",
        os.path.join(tmp, "a/b/f2"),
    )
    cli(
        "paths",
        "empty name",
        "run",
        cfg("n3.yaml", [("name: forward_parking", "name: ''")]),
        "--trials",
        "1",
        "--plots",
        os.path.join(tmp, "f3"),
    )
    # Unbounded work
    bomb = ["a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]"] + [
        f"{n}: &{n} [" + ", ".join([f"*{p}"] * 9) + "]" for p, n in zip("abcdefgh", "bcdefghi")
    ]
    bombf = os.path.join(tmp, "bomb.yaml")
    open(bombf, "w").write("\n".join(bomb) + "\n")
    cli("bounded", "YAML alias bomb", "run", bombf)
    cli("bounded", "max_step 1e-9", "run", cfg("b1.yaml", append="simulation: {max_step: 1.0e-9}\n"), "--trials", "1")
    cli("bounded", "pieces 1e9", "run", cfg("b2.yaml", [("pieces: [5.0]", "pieces: [1.0e+9]")]), "--trials", "1")
    cli("bounded", "pieces 1e20", "run", cfg("b3.yaml", [("pieces: [5.0]", "pieces: [1.0e+20]")]), "--trials", "1")
    cli("bounded", "pieces 1e300", "run", cfg("b4.yaml", [("pieces: [5.0]", "pieces: [1.0e+300]")]), "--trials", "1")
    cli("bounded", "v2_terms 200", "run", cfg("b5.yaml", [("v2_terms: 3", "v2_terms: 200")]), "--trials", "1")
    cli("bounded", "start x -1e300", "run", cfg("b6.yaml", [("start: [-1.0,", "start: [-1.0e+300,")]), "--trials", "1")
    # Task frame
    cli(
        "frame",
        "shared z1 in the rotated frame accepted",
        "run",
        cfg(
            "t1.yaml",
            [
                ("start: [-1.0, 0.0, 0.7853981633974483, 0.0]", "start: [0.0, 0.0, 2.0, 0.0]"),
                ("goal:  [0.0, 0.0, 0.7853981633974483, 0.0]", "goal: [1.0, 0.4577, 2.0, 0.0]"),
            ],
        ),
        "--trials",
        "1",
    )
    cli(
        "frame",
        "feasible rotated task refused",
        "run",
        cfg(
            "t2.yaml",
            [
                ("start: [-1.0, 0.0, 0.7853981633974483, 0.0]", "start: [0.0, 0.0, 2.0, 0.0]"),
                ("goal:  [0.0, 0.0, 0.7853981633974483, 0.0]", "goal: [0.0, -1.0, 2.0, 0.0]"),
            ],
        ),
        "--trials",
        "1",
    )
    cli(
        "frame",
        "goal x off by 1e-12",
        "run",
        cfg("t3.yaml", [("goal:  [0.0,", "goal:  [-0.999999999999,")]),
        "--trials",
        "1",
    )
    # compare
    C = ["compare", "--quick", "--methods", "ilc", "--no-progress-bar"]
    cli(
        "compare",
        "--seeds 0 0",
        *C,
        "--seeds",
        "0",
        "0",
        "--scenarios",
        "forward_parking",
        "--out",
        os.path.join(tmp, "c1"),
    )
    cli(
        "compare",
        "--methods ilc ilc",
        "compare",
        "--quick",
        "--methods",
        "ilc",
        "ilc",
        "--scenarios",
        "forward_parking",
        "--out",
        os.path.join(tmp, "c2"),
    )
    cli(
        "compare", "--seeds -1", *C, "--seeds", "-1", "--scenarios", "forward_parking", "--out", os.path.join(tmp, "c3")
    )
    cli(
        "compare",
        "--scenarios chained_perturbed",
        *C,
        "--scenarios",
        "chained_perturbed",
        "--out",
        os.path.join(tmp, "c4"),
    )
    cli(
        "compare",
        "--scenarios cyclic_home_goal",
        *C,
        "--scenarios",
        "cyclic_home_goal",
        "--out",
        os.path.join(tmp, "c5"),
    )
    cli(
        "compare",
        "bad scenario after a good one",
        *C,
        "--scenarios",
        "forward_parking",
        "nope",
        "--out",
        os.path.join(tmp, "c6"),
    )
    cf = os.path.join(tmp, "c7")
    os.makedirs(cf)
    open(os.path.join(cf, "cells"), "w").write("")
    cli("compare", "cells/ is a file", *C, "--scenarios", "forward_parking", "--out", cf)
    # Actions and envs
    for desc, action in [
        ("complex action", "np.array([1+1j,0,0,0])"),
        ("numeric strings", "['1','2','3','4']"),
        ("datetime64", "np.array(['2020-01-01']*4, dtype='datetime64[D]')"),
        ("masked array", "np.ma.array([1.,2,3,4], mask=[0,1,0,0])"),
        ("10**400", "[10**400,0,0,0]"),
    ]:
        py(
            "actions",
            desc,
            f"""
            env = gym.make("ilc_steering/ChainedSteering-v0", config="forward_parking"); env.reset()
            try:
                env.step({action}); print("ACCEPTED")
            except ValueError as e: print("VALUEERROR", e)
        """,
        )
    py(
        "envs",
        "vector reset(seed=[1]) with 4 envs",
        """
        e = gym.make_vec("ilc_steering/ChainedSteering-v0", num_envs=4, vectorization_mode="vector_entry_point")
        try:
            e.reset(seed=[1]); print("ACCEPTED")
        except ValueError as x: print("VALUEERROR", x)
    """,
    )
    py(
        "envs",
        "num_envs=True",
        """
        try:
            mode = "vector_entry_point"
            gym.make_vec("ilc_steering/ChainedSteering-v0", num_envs=True, vectorization_mode=mode)
            print("ACCEPTED")
        except ValueError as x: print("VALUEERROR", x)
    """,
    )
    py(
        "envs",
        "vector render_mode rgb_array then render()",
        """
        try:
            mode = "vector_entry_point"
            e = gym.make_vec("ilc_steering/ChainedSteering-v0", 2, vectorization_mode=mode, render_mode="rgb_array")
        except ValueError as x: print("VALUEERROR", x); raise SystemExit
        e.reset(); e.render(); print("ACCEPTED")
    """,
    )
    py(
        "envs",
        "ChainedSteering-v0 with a cyclic config",
        """
        try:
            gym.make("ilc_steering/ChainedSteering-v0", config="cyclic_home_goal"); print("ACCEPTED")
        except ValueError as x: print("VALUEERROR", x)
    """,
    )
    for desc, opts in [
        ("cyclic options typo 'strt'", "{'strt': [0.1, 0, 0, 0]}"),
        ("cyclic options not a dict", "[1, 2]"),
        ("cyclic start within the chart margin", "{'start': [0, 0, 1.5703, 0]}"),
    ]:
        py(
            "envs",
            desc,
            f"""
            e = gym.make("ilc_steering/CyclicSteering-v0", config="cyclic_home_goal")
            try:
                e.reset(options={opts}); print("ACCEPTED")
            except ValueError as x: print("VALUEERROR", x)
        """,
        )
    py(
        "envs",
        "cycles='3'",
        """
        try:
            gym.make("ilc_steering/CyclicSteering-v0", config="cyclic_home_goal", cycles="3"); print("ACCEPTED")
        except ValueError as x: print("VALUEERROR", x)
    """,
    )
    py(
        "envs",
        "config=None",
        """
        try:
            gym.make("ilc_steering/ChainedSteering-v0", config=None); print("ACCEPTED")
        except ValueError as x: print("VALUEERROR", x)
    """,
    )
    cli(
        "envs",
        "action_bound above float32",
        "run",
        cfg("e1.yaml", [("v2_terms: 3", "v2_terms: 3\n  action_bound: [1.0e+39, 1.0, 1.0, 1.0]")]),
        "--trials",
        "1",
    )
    cli("envs", "start x -1e38", "run", cfg("e2.yaml", [("start: [-1.0,", "start: [-1.0e+38,")]), "--trials", "1")
    # Config messages
    cli("config", "duplicate YAML keys", "run", cfg("m1.yaml", append="name: again\n"), "--trials", "1")
    cli(
        "config",
        "1e-3 read as text",
        "run",
        cfg("m2.yaml", [("cartesian: 5.0e-4", "cartesian: 1e-3")]),
        "--trials",
        "5",
    )
    cli(
        "config",
        "car tolerance with an extra error key",
        "run",
        cfg("m3.yaml", [("orientation: 5.0e-4}", "orientation: 5.0e-4, error: 1.0e-9}")]),
        "--trials",
        "5",
    )
    cyc = (
        (CONFIGS / "cyclic_home_goal.yaml")
        .read_text()
        .replace("  segments:", "  action_bound: [1.0, 1.0]\n  segments:")
    )
    cp = os.path.join(tmp, "m4.yaml")
    Path(cp).write_text(cyc)
    cli("config", "cyclic action_bound of the wrong length", "run", cp, "--trials", "1")
    # Robustness maps and batches of plants (issue 16)
    out = os.path.join(tmp, "sweep")
    cli("sweep", "--grid 1", "sweep", "forward_parking", "--grid", "1", "--out", out)
    cli("sweep", "--grid 100000", "sweep", "forward_parking", "--grid", "100000", "--out", out)
    cli("sweep", "--range inverted", "sweep", "forward_parking", "--range", "1.5", "0.5", "--out", out)
    cli("sweep", "--range with a zero", "sweep", "forward_parking", "--range", "0", "1.5", "--out", out)
    cli("sweep", "--nu-b nan", "sweep", "forward_parking", "--nu-b", "nan", "--out", out)
    cli("sweep", "--methods sac (RL)", "sweep", "forward_parking", "--methods", "sac", "--out", out)
    cli("sweep", "a cyclic config", "sweep", "cyclic_home_goal", "--out", out)
    cli("sweep", "--out is a file", "sweep", "forward_parking", "--out", cfg("s1.yaml"))
    cli("sweep", "--backend unknown", "sweep", "forward_parking", "--backend", "spark", "--out", out)
    cli("compare", "--backend unknown", "compare", "--quick", "--backend", "spark", "--out", out)
    py(
        "sweep",
        "true_factors negative",
        """
        from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
        try:
            ChainedSteeringVectorEnv(2, "forward_parking", true_factors=[[1.0, 1.0], [-1.0, 1.0]]); print("ACCEPTED")
        except ValueError as x: print("VALUEERROR", x)
    """,
    )
    py(
        "sweep",
        "true_factors wrong shape",
        """
        from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
        try:
            ChainedSteeringVectorEnv(2, "forward_parking", true_factors=[1.0, 1.0]); print("ACCEPTED")
        except ValueError as x: print("VALUEERROR", x)
    """,
    )
    attacks += issue26_attacks(tmp, cfg)
    attacks += issue34_attacks(tmp, cfg)
    return attacks


LEARNERS = """
import time
import numpy as np
from ilc_steering.agents.ilc import make_ilc
from ilc_steering.errors import ParameterError


class Wrapped:
    def __init__(self, context, fail=None):
        self.inner, self.trial, self.fail, self.seed = make_ilc(context), 0, fail, context.seed

    def act(self, observation):
        self.trial += 1
        if self.fail is not None:
            self.fail(self)
        return self.inner.act(observation)

    def learn(self, info):
        self.inner.learn(info)

    def reset(self):
        self.inner.reset()


def _svd(self):
    if self.trial == 2:
        raise np.linalg.LinAlgError("SVD did not converge")


def _runtime(self):
    if self.trial == 2:
        raise RuntimeError("my learner broke")


def _parameter(self):
    raise ParameterError("my_gain", "must be below 1")


def _forever(self):
    while True:
        time.sleep(0.1)


def _seed1_fails(self):
    if self.seed == 1:
        raise RuntimeError("seed 1 fails")
    time.sleep(1.0)


svd = lambda context: Wrapped(context, _svd)
runtime = lambda context: Wrapped(context, _runtime)
parameter = lambda context: Wrapped(context, _parameter)
forever = lambda context: Wrapped(context, _forever)
seed1_fails = lambda context: Wrapped(context, _seed1_fails)


class NanAt3(Wrapped):
    def act(self, observation):
        action = super().act(observation)
        return action * np.nan if self.trial == 3 else action


nan_at_3 = NanAt3
"""

# A py attack prints ACCEPTED for bad input taken (or a wrong result), HANG for no bound in time.
SHELL = """
import json, os, shutil, subprocess, sys
from pathlib import Path


def cli(*argv, env=None, timeout=55):
    try:
        p = subprocess.run([sys.executable, "-m", "ilc_steering", *argv], capture_output=True, text=True,
                           timeout=timeout, env={**os.environ, **(env or {})})
    except subprocess.TimeoutExpired:
        print("HANG"); raise SystemExit
    if "Traceback" in p.stderr:
        print(p.stderr, file=sys.stderr)
    return p.returncode, p.stderr.strip(), p.stdout.strip()


def one_line(err):
    return len(err.splitlines()) == 1


def verdict(ok):
    print("CLEAR" if ok else "ACCEPTED")
"""

Q = ["--quick", "--no-progress-bar", "--priors", "nominal", "--scenarios", "forward_parking"]


def issue26_attacks(tmp: str, cfg: Any) -> list[tuple[str, str, str, Any]]:
    """Issue 26's classes: YAML surprises, the reader, outputs, keys, resumed data, lost results,
    bounds, culprits, round-off."""
    Path(tmp, "mylearners.py").write_text(LEARNERS)
    Path(tmp, "x_y.py").write_text("from ilc_steering.agents.ilc import make_ilc as z\n")
    Path(tmp, "x.py").write_text("from ilc_steering.agents.ilc import make_ilc_paper as y_z\n")
    out: list[tuple[str, str, str, Any]] = []

    def cli(cls: str, desc: str, *argv: str) -> None:
        out.append((cls, desc, "cli", list(argv)))

    def shell(cls: str, desc: str, code: str) -> None:
        out.append((cls, desc, "py", SHELL + textwrap.dedent(code)))

    q = " ".join(repr(a) + "," for a in Q)
    # YAML: integers strictly, merge keys, size before reading, depth
    cli("yaml", "trials: 010 (YAML 1.1 octal)", "run", cfg("y1.yaml", [("trials: 10 ", "trials: 010 ")]))
    cli("yaml", "trials: 1:30 (sexagesimal)", "run", cfg("y2.yaml", [("trials: 10 ", "trials: 1:30 ")]))
    merge = "  tolerance: {cartesian: 5.0e-4, orientation: 5.0e-4}"
    cli(
        "yaml",
        "a valid merge key <<",
        "run",
        cfg("y3.yaml", [(merge, "  tolerance:\n    <<: {cartesian: 5.0e-4}\n    orientation: 5.0e-4")]),
        "--trials",
        "5",
    )
    big = os.path.join(tmp, "huge.yaml")
    with open(big, "wb") as f:
        f.write((CONFIGS / "forward_parking.yaml").read_bytes())
        f.truncate(600 << 20)  # sparse: 600 MB of zero bytes after the config
    cli("yaml", "a 600 MB config", "run", big)
    deep = os.path.join(tmp, "deep.yaml")
    Path(deep).write_text("name: " + "[" * 20000 + "]" * 20000 + "\n")
    cli("yaml", "nesting 20000 deep", "run", deep)
    # The reader of run files
    deep_json = os.path.join(tmp, "deep.json")
    Path(deep_json).write_text('{"kind": "trials", "x": ' + "[" * 100000 + "]" * 100000 + "}")
    cli("reader", "plot on JSON nested 100000 deep", "plot", deep_json, "--out", os.path.join(tmp, "p3"))
    huge_json = os.path.join(tmp, "huge.json")
    with open(huge_json, "wb") as f:
        f.write(b'{"kind": "trials", "x": "')
        f.truncate(400 << 20)  # sparse: 400 MB
    cli("reader", "plot on a 400 MB JSON", "plot", huge_json, "--out", os.path.join(tmp, "p4"))
    # Outputs: special files refused, the umask kept
    shell(
        "outputs",
        "--json onto a FIFO",
        """
        os.mkfifo("fifo.json")
        rc, err, _ = cli("run", "forward_parking", "--trials", "1", "--json", "fifo.json")
        import stat
        verdict(stat.S_ISFIFO(os.lstat("fifo.json").st_mode) and rc == 2 and one_line(err))
        """,
    )
    shell(
        "outputs",
        "--json mode under umask 022",
        """
        os.umask(0o022)
        rc, err, _ = cli("run", "forward_parking", "--trials", "1", "--json", "mode.json")
        verdict(os.stat("mode.json").st_mode & 0o777 == 0o644)
        """,
    )
    # Results keyed by content
    shell(
        "keys",
        "compare resumed with another YAML of the same name",
        f"""
        text = Path({str(CONFIGS / "forward_parking.yaml")!r}).read_text()
        Path("same.yaml").write_text(text)
        args = [{q} "--methods", "ilc", "--seeds", "0", "--model-trials", "3", "--out", "k1"]
        args[args.index("forward_parking")] = "same.yaml"
        cli("compare", *args)
        first = json.loads(Path("k1/compare.json").read_text())["cells"][0]["best_error"]
        Path("same.yaml").write_text(text.replace("true_wheelbase: 0.22", "true_wheelbase: 0.3"))
        rc, err, _ = cli("compare", *args)
        again = json.loads(Path("k1/compare.json").read_text())["cells"][0]["best_error"] if rc == 0 else None
        verdict(rc == 2 and one_line(err) or (rc == 0 and again != first))
        """,
    )
    shell(
        "keys",
        "sweep resumed with another YAML of the same name",
        f"""
        text = Path({str(CONFIGS / "forward_parking.yaml")!r}).read_text()
        Path("same.yaml").write_text(text)
        args = ["same.yaml", "--grid", "2", "--trials", "3", "--workers", "1", "--out", "k2"]
        cli("sweep", *args)
        first = json.loads(Path("k2/sweep.json").read_text())["rows"]
        Path("same.yaml").write_text(text.replace("nu_a: 1.0 ", "nu_a: 0.3 "))
        rc, err, _ = cli("sweep", *args)
        again = json.loads(Path("k2/sweep.json").read_text())["rows"] if rc == 0 else None
        verdict(rc == 2 and one_line(err) or (rc == 0 and again != first))
        """,
    )
    cli("keys", "sweep --methods ilc ilc", "sweep", "forward_parking", "--methods", "ilc", "ilc", "--out", "k3")
    cli("keys", "sweep --nu-b 1 1", "sweep", "forward_parking", "--nu-b", "1", "1", "--out", "k4")
    shell(
        "keys",
        "sweep gains 0.1234567 and 0.1234568 (one file name under :g)",
        """
        rc, err, _ = cli("sweep", "forward_parking", "--nu-b", "0.1234567", "0.1234568", "--grid", "2",
                         "--trials", "2", "--workers", "1", "--out", "k5")
        maps = json.loads(Path("k5/sweep.json").read_text())["maps"] if rc == 0 else {}
        verdict(rc == 2 and one_line(err) or len(maps) == 2)
        """,
    )
    shell(
        "keys",
        "users' methods x_y:z and x:y_z",
        f"""
        args = [{q} "--methods", "x_y:z", "x:y_z", "--seeds", "0", "--custom-trials", "3", "--out", "k6"]
        rc, err, _ = cli("compare", *args)
        cells = json.loads(Path("k6/compare.json").read_text())["cells"] if rc == 0 else []
        rc2, err2, _ = cli("compare", *args)
        verdict(rc == 0 and rc2 == 0 and sorted(c["method"] for c in cells) == ["x:y_z", "x_y:z"])
        """,
    )
    # Resumed data validated
    for folder, (desc, edit) in enumerate(
        (
            ("a sweep row with trials_to 999 (budget 3)", "row['trials_to'][0] = 999"),
            ("a sweep row with a negative wall time", "row['wall_s'] = -5.0"),
        )
    ):
        shell(
            "resumed",
            desc,
            f"""
            args = ["forward_parking", "--grid", "2", "--trials", "3", "--workers", "1", "--out", "rs{folder}"]
            cli("sweep", *args)
            path = sorted(Path("rs{folder}/rows").glob("*.json"))[0]
            row = json.loads(path.read_text()); {edit}; path.write_text(json.dumps(row))
            rc, err, _ = cli("sweep", *args)
            verdict(rc == 2 and one_line(err) and path.name in err)
            """,
        )
    for folder, (desc, edit) in enumerate(
        (
            ("a cell with a NaN best error", "cell['best_error'] = float('nan')"),
            ("a cell with a negative wall time", "cell['wall_s'] = -1.0"),
            ("a cell 700 % off the chart", "cell['off_chart_fraction'] = 7.0"),
        )
    ):
        shell(
            "resumed",
            desc,
            f"""
            args = [{q} "--methods", "ilc", "--seeds", "0", "--model-trials", "3", "--out", "rc{folder}"]
            cli("compare", *args)
            path = sorted(Path("rc{folder}/cells").glob("*.json"))[0]
            cell = json.loads(path.read_text()); {edit}; path.write_text(json.dumps(cell))
            rc, err, _ = cli("compare", *args)
            verdict(rc == 2 and one_line(err) and path.name in err)
            """,
        )
    # Nothing finished is lost
    shell(
        "lost",
        "a cell fails while another runs",
        f"""
        rc, err, out = cli("compare", {q} "--methods", "mylearners:seed1_fails", "--seeds", "0", "1",
                           "--custom-trials", "3", "--workers", "2", "--out", "l1")
        cells = [p.name for p in Path("l1/cells").glob("*.json")]
        last = [*out.splitlines(), *err.splitlines()][-1]
        verdict(len(cells) >= 1 and rc not in (0, 2, 3) and "1" in last and "fail" in last)
        """,
    )
    # Bounds in time and memory
    cli("bounds", "compare --workers 1000", "compare", *Q, "--methods", "ilc", "--workers", "1000", "--out", "w")
    cli("bounds", "run --trials 1000000000", "run", "forward_parking", "--trials", "1000000000")
    cli(
        "bounds",
        "compare --model-trials 1000000000",
        "compare",
        *Q,
        "--methods",
        "ilc",
        "--seeds",
        "0",
        "--model-trials",
        "1000000000",
        "--out",
        "w2",
    )
    shell(
        "bounds",
        "a learner that never returns, --cell-timeout 5",
        f"""
        rc, err, out = cli("compare", {q} "--methods", "mylearners:forever", "--seeds", "0", "--custom-trials", "3",
                           "--workers", "1", "--cell-timeout", "5", "--out", "b1", timeout=50)
        if rc == 2 and "unrecognized arguments: --cell-timeout" in err:
            print("HANG"); raise SystemExit  # no time limit to give
        verdict(rc not in (0, 2, 3) and ("timeout" in (out + err).lower() or "time limit" in (out + err).lower()))
        """,
    )
    shell(
        "bounds",
        "an unreachable RAY_ADDRESS",
        f"""
        rc, err, _ = cli("compare", {q} "--methods", "ilc", "--seeds", "0", "--backend", "ray", "--out", "b2",
                         env={{"RAY_ADDRESS": "10.255.255.1:6379"}}, timeout=45)
        verdict(rc == 2 and one_line(err) and "RAY_ADDRESS" in err)
        """,
    )
    # Errors name the culprit
    for folder, (desc, method) in enumerate(
        (
            ("a user learner's SVD failure (a ValueError)", "mylearners:svd"),
            ("a user learner's RuntimeError", "mylearners:runtime"),
            ("a user learner's ParameterError in a worker", "mylearners:parameter"),
        )
    ):
        shell(
            "culprit",
            desc,
            f"""
            rc, err, out = cli("compare", {q} "--methods", {method!r}, "--seeds", "0", "1", "--custom-trials", "3",
                               "--workers", "2", "--out", "e{folder}")
            text = out + err
            named = {method!r} in text and "seed" in text and "forward_parking" in text
            verdict(rc not in (0, 2, 3) and named and "bug" not in text and "BrokenProcessPool" not in text)
            """,
        )
    shell(
        "culprit",
        "run: a learner's NaN in trial 3",
        """
        rc, err, out = cli("run", "forward_parking", "--learner", "mylearners:nan_at_3", "--json", "nan.json")
        trials = json.loads(Path("nan.json").read_text())["trials"] if Path("nan.json").exists() else []
        verdict(rc not in (0, 2, 3) and "mylearners:nan_at_3" in err and len(trials) == 2)
        """,
    )
    # Numerics: an ill-posed task, a coarse integrator step
    chained = (CONFIGS / "chained_perturbed.yaml").read_text()
    mirrored = chained.replace("goal:  [1.0,", "goal:  [0.0,").replace("v1_fixed: [0.5]", "v1_fixed: [-0.5]")
    Path(tmp, "mirrored.yaml").write_text(mirrored)
    cli("numerics", "a task whose mirrored v1 pieces make W singular", "run", os.path.join(tmp, "mirrored.yaml"))
    cli(
        "numerics",
        "max_step 1.0 (2 mm off the fine simulation)",
        "run",
        cfg("n4.yaml", append="simulation: {max_step: 1.0}\n"),
        "--trials",
        "5",
    )
    # Counts never decided by round-off
    out.append(
        (
            "counts",
            "an error 1e-12 above the level counted as met",
            "py",
            PRE
            + textwrap.dedent(
                """
                from ilc_steering.compare.cells import TrialLog, first_within
                log = TrialLog()
                log.cartesian, log.orientation, log.left_chart = [0.01 * (1 + 1e-12)], [0.0], [False]
                print("ACCEPTED" if first_within(log, 0.01) == 1 else "CLEAR")
                """
            ),
        )
    )
    return out


def issue34_attacks(tmp: str, cfg: Any) -> list[tuple[str, str, str, Any]]:
    """Issue 34's classes this battery can replay in one process each: files that block or crash
    (3), plugins (4), the environment (5), physical ranges (6), wrappers and vector envs (9), RL
    hyperparameters (10) and small ones (12)."""
    out: list[tuple[str, str, str, Any]] = []

    def cli(cls: str, desc: str, *argv: str) -> None:
        out.append((cls, desc, "cli", list(argv)))

    def py(cls: str, desc: str, code: str) -> None:
        out.append((cls, desc, "py", PRE + textwrap.dedent(code)))

    fifo = os.path.join(tmp, "run.fifo")
    os.mkfifo(fifo)
    loop = os.path.join(tmp, "loop.json")
    os.symlink(loop, loop)
    dangling = os.path.join(tmp, "dangling.json")
    os.symlink(os.path.join(tmp, "nowhere", "x.json"), dangling)
    plain = os.path.join(tmp, "plain")
    Path(plain).write_text("x")
    cli("files34", "plot on a FIFO", "plot", fifo, "--out", os.path.join(tmp, "pf"))
    cli("files34", "plot on a symlink loop", "plot", loop, "--out", os.path.join(tmp, "pl"))
    cli("files34", "--json under a regular file", "run", "forward_parking", "--trials", "1", "--json",
        os.path.join(plain, "x.json"))  # fmt: skip
    cli("files34", "--json a symlink loop", "run", "forward_parking", "--trials", "1", "--json", loop)
    cli("files34", "--json a name too long", "run", "forward_parking", "--trials", "1", "--json",
        os.path.join(tmp, "n" * 300 + ".json"))  # fmt: skip
    cli("files34", "--plots a FIFO", "run", "forward_parking", "--trials", "1", "--plots", fifo)
    plugin = """
        import sys, types, importlib.metadata as md
        from pathlib import Path
        root = Path("plugin34"); root.mkdir(exist_ok=True)
        (root / "broken_plugin.py").write_text("raise RuntimeError('plugin broke')")
        info = root / "broken-0.1.dist-info"; info.mkdir(exist_ok=True)
        (info / "METADATA").write_text("Metadata-Version: 2.1\\nName: broken\\nVersion: 0.1\\n")
        (info / "entry_points.txt").write_text("[ilc_steering.robots]\\n{name} = broken_plugin:Config\\n")
        sys.path.insert(0, str(root))
        from ilc_steering.config import load_config
        {check}
        """
    unrelated = 'print("CLEAR" if load_config("forward_parking").name == "forward_parking" else "ACCEPTED")'
    packaged = (
        'import ilc_steering.core.robots as r; ok = r.config_class("car").__module__.startswith("ilc_steering"); '
    )
    packaged += 'print("CLEAR" if ok else "ACCEPTED")'
    for name, desc, check in (
        ("rover", "a plugin that raises breaks an unrelated run", unrelated),
        ("car", "a plugin that registers car", packaged),
    ):
        py("plugins34", desc, plugin.replace("{name}", name).replace("{check}", check))  # fmt: skip
    py("plugins34", "a plain dataclass as plant.model", """
        from dataclasses import dataclass
        from ilc_steering.config import load_config
        import yaml
        data = yaml.safe_load(open("forward34.yaml").read()); data["plant"]["model"] = "dataclasses:dataclass"
        try:
            load_config(data); print("ACCEPTED")
        except ValueError as error:
            print("CLEAR" if "dataclass" in str(error) else "UNCLEAR")
        """)  # fmt: skip
    Path(tmp, "forward34.yaml").write_text((CONFIGS / "forward_parking.yaml").read_text())
    py("env34", "ILC_STEERING_RL_BACKEND=jax", """
        import os; os.environ["ILC_STEERING_RL_BACKEND"] = "jax"
        from ilc_steering.agents.rl_settings import rl_backend
        try:
            rl_backend(); print("ACCEPTED")
        except ValueError as error:
            print("CLEAR" if "ILC_STEERING_RL_BACKEND" in str(error) else "UNCLEAR")
        """)  # fmt: skip
    cli("ranges34", "wheelbase 1e-300", "run", cfg("r1.yaml", [("wheelbase: 0.2 ", "wheelbase: 1.0e-300 ")]))
    cli("ranges34", "pieces of 1 us", "run", cfg("r2.yaml", [("pieces: [5.0]", "pieces: [1.0e-6]")]))
    cli(
        "ranges34",
        "start error of 1 km",
        "run",
        cfg("r3.yaml", append="simulation: {start_error: [1000.0, 0, 0, 0]}\n"),
    )
    py("ranges34", "vector env true factors 1e-300", """
        from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
        try:
            ChainedSteeringVectorEnv(2, config="forward_parking", true_factors=np.full((2, 2), 1e-300))
            print("ACCEPTED")
        except ValueError as error:
            print("CLEAR" if "1e-300" in str(error) else "UNCLEAR")
        """)  # fmt: skip
    py("wrappers34", "ResidualAction(scale=1e308)", """
        from ilc_steering.envs.wrappers import ResidualAction
        try:
            ResidualAction(gym.make("ilc_steering/ChainedSteering-v0"), scale=1e308); print("ACCEPTED")
        except ValueError:
            print("CLEAR")
        """)  # fmt: skip
    py("wrappers34", "CyclicSteeringVectorEnv(10**9)", """
        from ilc_steering.envs.cyclic_vector_env import CyclicSteeringVectorEnv
        try:
            CyclicSteeringVectorEnv(10**9); print("ACCEPTED")
        except ValueError:
            print("CLEAR")
        """)  # fmt: skip
    py("wrappers34", "ResidualAction under check_env", """
        from gymnasium.utils.env_checker import check_env
        from ilc_steering.envs.wrappers import ResidualAction
        check_env(ResidualAction(gym.make("ilc_steering/ChainedSteering-v0")), skip_render_check=True); print("CLEAR")
        """)  # fmt: skip
    py("wrappers34", "vector reset(seed=[1, 2]) ignores the second seed", """
        from ilc_steering.envs.steering_vector_env import ChainedSteeringVectorEnv
        rewards = []
        for seeds in ([1, 2], [1, 3]):
            envs = ChainedSteeringVectorEnv(2, config="forward_parking_noisy"); envs.reset(seed=seeds)
            c = envs.nominal_model.solve().astype(np.float32)
            rewards.append(envs.step(np.tile(c, (2, 1)))[1])
        print("CLEAR" if rewards[0][1] != rewards[1][1] and rewards[0][0] == rewards[1][0] else "ACCEPTED")
        """)  # fmt: skip
    for key, value in (("learning_rate", "-0.001"), ("batch_size", "256.5"), ("n_timesteps", "True")):
        py("rlyaml34", f"configs/rl/ppo.yaml {key}: {value}", f"""
            from ilc_steering.agents.rl_settings import check_hyperparameters, hyperparameters
            params = {{**hyperparameters("ppo", "forward_parking"), {key!r}: {value}}}
            try:
                check_hyperparameters("ppo", params, "configs/rl/ppo.yaml: nominal.default"); print("ACCEPTED")
            except ValueError as error:
                print("CLEAR" if {key!r} in str(error) and "ppo.yaml" in str(error) else "UNCLEAR")
            """)  # fmt: skip
    cli("small34", "YAML 0.0_2", "run", cfg("s1.yaml", append="simulation: {max_step: 0.0_2}\n"))
    cli("small34", "max_step coarser than a piece", "run", cfg("s2.yaml", append="simulation: {max_step: 6.0}\n"))
    return out


PRE = "import gymnasium as gym, numpy as np, ilc_steering\n"
# Attacks whose peak resident memory [MB] must stay below a bound.
MEMORY_BOUND = {"a 600 MB config": 300, "plot on a 400 MB JSON": 300}
# Valid inputs that were once refused or mishandled: these must run.
VALID = {"feasible rotated task refused", "--scenarios chained_perturbed", "1e-3 read as text", "a valid merge key <<"}


def classify(cls: str, desc: str, kind: str, payload: Any, python: str, tmp: str) -> dict[str, str]:
    argv = [python, "-c", payload] if kind == "py" else [python, "-m", "ilc_steering", *payload]
    if desc in MEMORY_BOUND:
        argv = ["/usr/bin/time", "-f", "MAXRSS %M", *argv]
    try:
        p = subprocess.run(argv, capture_output=True, text=True, timeout=60, cwd=tmp)
    except subprocess.TimeoutExpired:
        return {"class": cls, "attack": desc, "verdict": "hang", "message": ""}
    out, err, rc = p.stdout, p.stderr, p.returncode
    rss_kib = 0
    if desc in MEMORY_BOUND:
        *rest, last = err.rstrip().splitlines() or [""]
        rss_kib = int(last.split()[-1]) if last.startswith("MAXRSS") else 0
        err = "\n".join(line for line in rest if not line.startswith("Command exited with non-zero status"))
        if rss_kib > MEMORY_BOUND[desc] * 1024:
            message = f"peak memory {rss_kib // 1024} MB"
            return {"class": cls, "attack": desc, "verdict": "blow-up", "message": message}
    if "Traceback" in err or rc not in (0, 1, 2):
        verdict = "traceback"
    elif kind == "py":
        verdict = (
            "hang"
            if "HANG" in out
            else "silent"
            if "ACCEPTED" in out
            else "clear"
            if "CLEAR" in out or "VALUEERROR" in out
            else "unclear"
        )
    elif desc in VALID:
        verdict = "clear" if rc in (0, 1) and "error" not in err else "refused a valid input"
    else:
        verdict = (
            "clear" if rc == 2 and len(err.strip().splitlines()) == 1 else ("silent" if rc in (0, 1) else "unclear")
        )
        if verdict == "silent" and "warning:" in err:
            verdict = "warned"  # taken, with a one-line warning that names the key
    if desc == "1e-3 read as text" and rc in (0, 1) and "converged at trial" not in out:
        verdict = "silent"
    if verdict == "clear" and kind == "cli" and cls in ("cli", "config", "bounded", "paths", "envs"):
        named = [os.path.basename(a) for a in payload if a.endswith((".yaml", ".json"))]
        if named and rc == 2 and not any(n in err for n in named):
            verdict = "unclear"
    if desc == "bad scenario after a good one":
        cells = os.path.join(tmp, "c6", "cells")
        if os.path.isdir(cells) and os.listdir(cells):
            verdict = "late"
    message = err.strip().splitlines()[-1][:160] if err.strip() else ""
    return {"class": cls, "attack": desc, "verdict": verdict, "message": message}


def main(args: Args) -> list[dict[str, str]]:
    with tempfile.TemporaryDirectory() as tmp:
        chosen = attacks(tmp)
        if args.quick:
            chosen = [a for i, a in enumerate(chosen) if i == 0 or a[0] != chosen[i - 1][0]]
        results = []
        for attack in chosen:
            results.append(classify(*attack, args.python, tmp))
            print(f"{results[-1]['class']:8s} {results[-1]['verdict']:10s} {results[-1]['attack']}", flush=True)
    counts = collections.Counter(r["verdict"] for r in results)
    by_class = collections.Counter(r["class"] for r in results if r["verdict"] not in ("clear", "warned"))
    classes = list(dict.fromkeys(r["class"] for r in results))
    rows = [[c, str(sum(r["class"] == c for r in results)), str(by_class[c])] for c in classes]
    text = markdown_table(["class", "attacks", "not clear"], rows, [False, True, True])
    text += "\nOutcomes: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + "\n"
    write_results(results, args.out, "bad_inputs", text)
    print(text)
    return results


def parse(argv: list[str] | None = None) -> Args:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the first attack of each class only (CI)")
    parser.add_argument("--python", default=Args.python, help="the interpreter whose ilc_steering is attacked")
    parser.add_argument("--out", type=Path, default=Args.out)
    ns = parser.parse_args(argv)
    return Args(quick=ns.quick, python=ns.python, out=ns.out)


if __name__ == "__main__":
    arguments = parse()
    main(arguments)
    record_made(arguments.out, __file__, sys.argv[1:])
