"""A result's closure holds every module its computation imports (issue 67).

The closure is read from the sources (:mod:`ilc_steering.engine.closure`); what a computation
really imports is what a fresh process holds in ``sys.modules`` after it. A module imported but
not in the closure would be a change that stales nothing: these tests run a cell and a row each
in a fresh process and check that none is.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from ilc_steering.compare.cells import cell_roots
from ilc_steering.config import load_config
from ilc_steering.engine.closure import BOOKKEEPING, closure
from ilc_steering.sweep.rows import oracle_roots, row_roots


def modules_of(files: dict[str, str]) -> set[str]:
    """The module names of a closure's ``.py`` files."""
    return {key.removesuffix(".py").removesuffix("/__init__").replace("/", ".") for key in files if key.endswith(".py")}


def imported(code: str) -> set[str]:
    """The library's modules a fresh process holds after running ``code``."""
    tail = (
        "\nimport json as _json, sys as _sys\n"
        "print(_json.dumps(sorted(n for n, m in _sys.modules.items() if n.split('.')[0] == 'ilc_steering' "
        "and getattr(m, '__file__', None))))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code) + tail], capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    return set(json.loads(done.stdout.strip().splitlines()[-1])) - BOOKKEEPING  # records, not results


def robot(config: str) -> str:
    return type(load_config(config).plant).__module__


def test_the_closure_reads_lazy_tables_relative_imports_and_skips_type_checking(tmp_path) -> None:
    files = closure(["ilc_steering.compare.plan"])
    assert "ilc_steering/compare/args.py" in files  # imported for real there
    cells = closure(["ilc_steering.compare.cells"])
    assert "ilc_steering/compare/args.py" not in cells  # only under TYPE_CHECKING
    script = tmp_path / "mine.py"
    code = "def wrap(env):\n    from ilc_steering.envs import ResidualAction\n\n    return ResidualAction(env)\n"
    script.write_text(code)
    lazy = closure([str(script)])  # a name of envs/__init__.py's lazy table: the module it names
    assert "ilc_steering/envs/wrappers.py" in lazy and "ilc_steering/envs/base.py" in lazy
    beside = closure(["benchmarks/highway_table.py"])
    assert "benchmarks/highway_parking.py" in beside  # a script's import of the file beside it
    with pytest.raises(ValueError, match="no module of ilc_steering"):
        closure(["ilc_steering.agents.no_such_learner"])


def test_the_records_keepers_are_in_no_closure_but_their_own() -> None:
    noisy = closure(["benchmarks/noisy.py"])  # imports record_made
    assert "ilc_steering/core/integrate.py" in noisy
    assert not {key for key in noisy if modules_of({key: ""}) & BOOKKEEPING}  # a change to them stales nothing
    own = closure(["ilc_steering.engine.provenance"])
    assert "ilc_steering/engine/provenance.py" in own and "ilc_steering/engine/closure.py" not in own


@pytest.mark.slow
@pytest.mark.parametrize(
    ("method", "config"),
    [
        ("ilc", "forward_parking"),
        ("robust_ilc", "experiment_parallel"),
        ("newton_ilc", "trailer_bay"),
        ("least_squares", "unicycle_parking"),
        ("ppo", "forward_parking"),
    ],
)
def test_a_cell_imports_nothing_outside_its_closure(method: str, config: str) -> None:
    found = imported(f"""
        from ilc_steering.compare.args import Args
        from ilc_steering.compare.cells import run_cell
        run_cell(Args(), "nominal", {method!r}, {config!r}, 0, trials=2)
    """)
    outside = found - modules_of(closure(cell_roots(method, robot(config))))
    assert not outside, f"imported by a {method} cell on {config}, not in its closure: {sorted(outside)}"


@pytest.mark.slow
def test_a_row_and_the_oracle_import_nothing_outside_their_closure() -> None:
    args = "SweepArgs(config='forward_parking', grid=2, trials=2)"
    row = imported(f"from ilc_steering.sweep.rows import SweepArgs, run_row\nrun_row({args}, 'newton_ilc', None, 0)")
    outside = row - modules_of(closure(row_roots("newton_ilc", robot("forward_parking"))))
    assert not outside, f"imported by a row, not in its closure: {sorted(outside)}"
    oracle = imported(f"from ilc_steering.sweep.rows import SweepArgs, run_oracle\nrun_oracle({args})")
    outside = oracle - modules_of(closure(oracle_roots(robot("forward_parking"))))
    assert not outside, f"imported by the oracle, not in its closure: {sorted(outside)}"
