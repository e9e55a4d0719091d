"""A non-editable install ships every subpackage under the one name ilc_steering."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow  # builds a wheel
def test_wheel_ships_every_subpackage_and_config(tmp_path):
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path),
            str(ROOT),
        ],
        check=True,
        capture_output=True,
        timeout=600,
    )
    (wheel,) = tmp_path.glob("ilc_steering-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for folder, package in (
        ("envs", "ilc_steering/envs"),
        ("agents", "ilc_steering/agents"),
        ("ilc_steering", "ilc_steering"),
        ("ilc_steering/core", "ilc_steering/core"),
        ("ilc_steering/core/robots", "ilc_steering/core/robots"),
    ):
        for source in (ROOT / folder).glob("*.py"):
            assert f"{package}/{source.name}" in names
    for config in [*(ROOT / "configs").rglob("*.yaml"), *(ROOT / "configs").rglob("*.yml")]:  # rl_zoo/*.yml
        assert f"ilc_steering/configs/{config.relative_to(ROOT / 'configs').as_posix()}" in names
    assert not any(n.startswith(("envs/", "agents/", "tests/", "benchmarks/")) for n in names)
