"""A robot config is a frozen dataclass, and its schema: every field type a user may write (bool,
int, float, str, Literal, tuples, nested dataclasses) is read strictly, a wrong value refused in one
line naming the file and the key, through the CLI (exit 2), never exit 3, never taken silently."""

import shutil
import textwrap
from pathlib import Path

import pytest

from ilc_steering.cli import main
from ilc_steering.core import robots

HERE = Path(__file__).resolve().parent

ROBOT = """
from dataclasses import dataclass, field
from typing import Literal

from toy_robot import SkatePlantConfig


@dataclass(frozen=True)
class Wheels:
    count: int = 4  # [-]
    radius: float = 0.02  # [m]


@dataclass(frozen=True)
class FlagSkate(SkatePlantConfig):
    model: Literal["flagskate"] = "flagskate"
    mirrored: bool = False  # a flag
    mode: Literal["glide", "push"] = "glide"  # a choice
    offset: tuple[float, float] = (0.0, 0.0)  # [m] exactly two numbers
    label: str = "skate"
    wheels: Wheels = field(default_factory=Wheels)  # a nested mapping
"""


@pytest.fixture(autouse=True)
def own_registry(monkeypatch):
    """The robots this file registers (``flagskate``) are gone after each test."""
    for name in ("ROBOTS", "_LOADED", "_SOURCES"):
        monkeypatch.setattr(robots, name, dict(getattr(robots, name)))


def write(tmp_path, plant):
    folder = tmp_path / "robot"
    folder.mkdir(exist_ok=True)
    shutil.copy(HERE / "toy_robot.py", folder / "toy_robot.py")
    (folder / "flag_skate.py").write_text(ROBOT)
    text = (HERE / "toy_robot.py").read_text().split('CONFIG = """\\\n')[1].split('"""')[0]
    head, tail = text.split("plant:\n", 1)
    tail = tail.split("task:", 1)[1]
    lines = "".join(f"  {line}\n" for line in textwrap.dedent(plant).strip().splitlines())
    path = folder / "flag.yaml"
    path.write_text(f"{head}plant:\n  model: flag_skate:FlagSkate\n{lines}task:{tail}")
    return path


GOOD = """
mirrored: true
mode: push
offset: [0.1, -0.2]
label: left
wheels: {count: 3, radius: 0.025}
"""


def test_every_field_type_loads(tmp_path):
    from ilc_steering.config import load_config

    plant = load_config(write(tmp_path, GOOD)).plant
    assert (plant.mirrored, plant.mode, plant.offset, plant.label) == (True, "push", (0.1, -0.2), "left")
    assert (plant.wheels.count, plant.wheels.radius) == (3, 0.025)


@pytest.mark.parametrize(
    ("plant", "message"),
    [
        ("mirrored: 'yes'", "plant.mirrored: must be true or false, got 'yes'"),
        ("mirrored: 1", "plant.mirrored: must be true or false, got 1"),
        ("mode: skid", "plant.mode: must be one of ['glide', 'push'], got 'skid'"),
        ("offset: [0.1]", "plant.offset: needs 2 values, got 1"),
        ("offset: [0.1, 0.2, 0.3]", "plant.offset: needs 2 values, got 3"),
        ("offset: 0.1", "plant.offset: must be a list, got 0.1"),
        ("label: 3", "plant.label: must be a string, got 3"),
        ("wheels: {count: 2.5}", "plant.wheels.count: must be an integer, got 2.5"),
        ("wheels: {spokes: 2}", "plant.wheels.spokes: unknown key"),
        ("wheels: [1, 2]", "plant.wheels: must be a mapping"),
        ("true_speed_gain: .nan", "plant.true_speed_gain: must be a finite number"),
        ("true_speed_gain: '1.1'", "plant.true_speed_gain: must be a number, got '1.1'"),
        ("true_speed_gain: 010", "plant.true_speed_gain: '010' is ambiguous"),
        ("true_speed_gain: -1.0", "plant.true_speed_gain: must be finite and > 0"),
        ("colour: red", "plant.colour: unknown key; allowed keys here: ["),
    ],
)
def test_a_wrong_value_is_refused_in_one_line_naming_the_file_and_the_key(tmp_path, capsys, plant, message):
    path = write(tmp_path, plant)
    assert main(["run", str(path), "--trials", "1", "--hold", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert str(path) in err and message in err, err
