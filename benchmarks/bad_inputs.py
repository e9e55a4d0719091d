"""Bad inputs, replayed: issue 12's defect lines against an installed ilc-steering, each outcome classified.

Each attack runs in a fresh interpreter (``--python``, default: this one) with a 60 s limit and
is classified as ``clear`` (a one-line error that names the file, key or option, exit 2, or a
``ValueError``; or, for the few valid inputs once refused, a normal run), ``traceback``,
``hang``, ``silent`` (bad input taken without a word, or a wrong result), ``unclear`` (an error
that names no file), ``late`` (found after work was done) or ``refused a valid input``. Point
``--python`` at another install (an older version in its own virtual environment) to compare.

    python benchmarks/bad_inputs.py [--quick] [--python PY] [--out DIR]
"""

from __future__ import annotations

import argparse
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

from ilc_steering.config import load_config
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
    return attacks


PRE = "import gymnasium as gym, numpy as np, ilc_steering\n"
# Valid inputs that were once refused or mishandled: these must run.
VALID = {"feasible rotated task refused", "--scenarios chained_perturbed", "1e-3 read as text"}


def classify(cls: str, desc: str, kind: str, payload: Any, python: str, tmp: str) -> dict[str, str]:
    argv = [python, "-c", payload] if kind == "py" else [python, "-m", "ilc_steering", *payload]
    try:
        p = subprocess.run(argv, capture_output=True, text=True, timeout=60, cwd=tmp)
    except subprocess.TimeoutExpired:
        return {"class": cls, "attack": desc, "verdict": "hang", "message": ""}
    out, err, rc = p.stdout, p.stderr, p.returncode
    if "Traceback" in err or rc not in (0, 1, 2):
        verdict = "traceback"
    elif kind == "py":
        verdict = "silent" if "ACCEPTED" in out else "clear"
    elif desc in VALID:
        verdict = "clear" if rc in (0, 1) and "error" not in err else "refused a valid input"
    else:
        verdict = (
            "clear" if rc == 2 and len(err.strip().splitlines()) == 1 else ("silent" if rc in (0, 1) else "unclear")
        )
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
    by_class = collections.Counter(r["class"] for r in results if r["verdict"] != "clear")
    classes = list(dict.fromkeys(r["class"] for r in results))
    rows = [[c, str(sum(r["class"] == c for r in results)), str(by_class[c])] for c in classes]
    text = markdown_table(["class", "attacks", "not clear"], rows, [False, True, True])
    text += "\nOutcomes: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + "\n"
    write_results(results, args.out, "bad_inputs", text)
    print(text)
    return results


def parse(argv: list[str] | None = None) -> Args:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the first attack of each class only (CI)")
    parser.add_argument("--python", default=Args.python, help="the interpreter whose ilc_steering is attacked")
    parser.add_argument("--out", type=Path, default=Args.out)
    ns = parser.parse_args(argv)
    return Args(quick=ns.quick, python=ns.python, out=ns.out)


if __name__ == "__main__":
    main(parse())
