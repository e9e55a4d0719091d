"""Issue 34, class 4 (and issue 32's robot protocol): a plugin cannot break the library.

An installed ``ilc_steering.robots`` entry point is a string until a config names its robot, so a
broken one (a module that raises, a syntax error, a class that is not a robot's config) breaks only
the configs that use it, each with a one-line error naming the package and the entry point; one
that would replace a packaged robot or has a malformed name is skipped with a warning.
"""

from __future__ import annotations

import json
import re
import sys
import textwrap
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ilc_steering.config import load_config
from ilc_steering.core import robots
from ilc_steering.errors import ConfigError

HERE = Path(__file__).parent
FORWARD = (HERE.parent / "configs" / "forward_parking.yaml").read_text()

GOOD = "from ilc_steering.core.robots.unicycle import UnicyclePlantConfig as Base\n"
MODULES = {
    "raises": "raise RuntimeError('the plugin broke')\n",
    "syntax": "def broken(:\n",
    "not_a_class": "Config = 42\n",
    "plain_dataclass": "from dataclasses import dataclass\n@dataclass(frozen=True)\nclass Config:\n    model: str\n",
    "not_frozen": "from dataclasses import dataclass\nfrom typing import Literal\n"
    "@dataclass\nclass Config:\n    model: Literal['{name}']\n",
    "missing_method": "from dataclasses import dataclass\nfrom typing import Literal\n"
    "@dataclass(frozen=True)\nclass Config:\n    model: Literal['{name}']\n    kind = None\n    plant_class = object\n"
    "    dimension = 3\n    steering_limit = None\n    def plant(self): ...\n    def nominal_map(self): ...\n",
    "missing_import": "Config = 1\n",  # the entry names an attribute that is not there
}
BROKEN = sorted(MODULES)


@pytest.fixture
def fresh(monkeypatch, tmp_path):
    """A registry as a fresh process has it, and a folder on ``sys.path`` for plugin packages."""
    monkeypatch.setattr(robots, "ROBOTS", dict({k: robots.ROBOTS[k] for k in robots.PACKAGED}))
    monkeypatch.setattr(robots, "_LOADED", {})
    monkeypatch.setattr(robots, "_PLUGINS", [])
    monkeypatch.setattr(robots, "_SOURCES", {})
    monkeypatch.setattr(robots, "_SKIPPED", {})
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def _install(root: Path, package: str, name: str, module_text: str, attribute: str = "Config") -> str:
    """A distribution ``package`` with one entry point ``name = <module>:attribute``; its module's name."""
    module = f"plug_{package.replace('-', '_')}"
    (root / f"{module}.py").write_text(module_text)
    info = root / f"{package}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {package}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[ilc_steering.robots]\n{name} = {module}:{attribute}\n")
    sys.modules.pop(module, None)
    return module


def _config_of(root: Path, model: str) -> Path:
    text = FORWARD.replace("model: car", f"model: {model!r}", 1)
    path = root / "plugged.yaml"
    path.write_text(text)
    return path


_PACKAGES = st.text(st.sampled_from("abcdefgh"), min_size=3, max_size=8).map(lambda s: f"pkg-{s}")


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(BROKEN), package=_PACKAGES, name=st.sampled_from(["skate", "rover", "dozer"]))
def test_a_broken_plugin_breaks_only_its_own_robot_naming_the_package(fresh, capsys, kind, package, name):
    root = fresh / f"{kind}-{package}-{name}"
    root.mkdir()
    sys.path.insert(0, str(root))
    try:
        for state in (robots._LOADED, robots._SOURCES, robots._SKIPPED):
            state.clear()
        robots._PLUGINS.clear()
        robots.ROBOTS.pop(name, None)
        attribute = "Missing" if kind == "missing_import" else "Config"
        _install(root, package, name, MODULES[kind].format(name=name), attribute)
        assert load_config("forward_parking").plant.model == "car"  # a command that does not need it
        with pytest.raises(ConfigError) as caught:
            load_config(_config_of(root, name))
        message = str(caught.value)
        assert "\n" not in message and "plant.model" in message
        assert f"package {package}" in message and f"{name} = " in message
    finally:
        sys.path.remove(str(root))


@pytest.mark.parametrize("name", sorted(robots.PACKAGED))
def test_a_plugin_cannot_replace_a_packaged_robot(fresh, capsys, name):
    _install(fresh, "evil-robots", name, GOOD.replace("as Base", "as Config"))
    packaged = robots.ROBOTS[name].partition(":")[0]
    assert robots.config_class(name).__module__ == packaged
    err = capsys.readouterr().err
    assert f"evil-robots: {name} = " in err and "cannot replace" in err and err.count("\n") == 1
    assert any("evil-robots" in where for where in robots.skipped())


def test_a_plugin_with_a_malformed_name_is_skipped_with_a_warning(fresh, capsys):
    _install(fresh, "odd-robots", "Bad-Name", GOOD.replace("as Base", "as Config"))
    assert "Bad-Name" not in robots.names()
    assert "odd-robots: Bad-Name" in capsys.readouterr().err


def test_a_plain_dataclass_is_not_a_plant_config(fresh):
    module = _install(fresh, "plain-robots", "plain", MODULES["plain_dataclass"])
    with pytest.raises(ConfigError, match=r"plant\.model: .*Config.*docs/robots\.md"):
        load_config(_config_of(fresh, f"{module}:Config"))


def test_a_missing_method_is_named_when_the_config_loads(fresh):
    module = _install(fresh, "half-robots", "half", MODULES["missing_method"].format(name="half"))
    with pytest.raises(ConfigError, match=r"has no 'check_task'"):
        load_config(_config_of(fresh, f"{module}:Config"))


def test_plant_model_takes_module_colon_class_like_learner(fresh):
    (fresh / "my_unicycle.py").write_text(
        textwrap.dedent(
            """
            from dataclasses import dataclass
            from typing import Literal
            from ilc_steering.core.robots.unicycle import UnicyclePlantConfig

            @dataclass(frozen=True)
            class Config(UnicyclePlantConfig):
                model: Literal["my_unicycle"]  # type: ignore[assignment]
            """
        )
    )
    text = (HERE.parent / "configs" / "unicycle_parking.yaml").read_text()
    path = fresh / "mine.yaml"
    path.write_text(text.replace("  model: unicycle", "  model: my_unicycle:Config", 1))
    config = load_config(path)
    assert config.plant.model == "my_unicycle" and type(config.plant).__name__ == "Config"
    assert load_config(path) == config  # registered once, loaded again the same
    with pytest.raises(ConfigError, match="registered already"):
        (fresh / "other.py").write_text("from my_unicycle import Config\n")
        path.write_text(text.replace("  model: unicycle", "  model: 'other:Config'", 1))
        load_config(path)  # the same name from another entry: refused, not replaced


HOSTILE_ROBOTS = """
import sys
from dataclasses import dataclass
from typing import Literal

from ilc_steering.core.robots.unicycle import UnicycleModel, UnicyclePlantConfig


@dataclass(frozen=True)
class Raising(UnicyclePlantConfig):
    model: Literal["raising"]

    def __post_init__(self):
        raise RuntimeError("my __post_init__ exploded")


@dataclass(frozen=True)
class PlantRaises(UnicyclePlantConfig):
    model: Literal["plant_raises"]

    def __post_init__(self):
        pass

    def plant(self):
        raise TypeError("my plant() exploded")


@dataclass(frozen=True)
class PlantExits(PlantRaises):
    model: Literal["plant_exits"]

    def plant(self):
        sys.exit(3)


@dataclass(frozen=True)
class NanNominal(UnicyclePlantConfig):
    model: Literal["nan_nominal"]

    def __post_init__(self):
        pass

    def nominal_map(self):
        return UnicycleModel(float("nan"), 0.1)
"""


@pytest.mark.parametrize(
    ("cls", "says"),
    [
        ("Raising", "plant.model 'hostile_robots:Raising': Raising raised RuntimeError: my __post_init__ exploded"),
        ("PlantRaises", "plant.model 'plant_raises' (hostile_robots:PlantRaises): PlantRaises.plant() raised "
         "TypeError: my plant() exploded"),
        ("PlantExits", "plant.model 'plant_exits' (hostile_robots:PlantExits): PlantExits.plant() raised "
         "SystemExit: 3"),
        ("NanNominal", "plant.model 'nan_nominal' (hostile_robots:NanNominal): NanNominal.plant() raised "
         "ParameterError: wheel_radius: must be a length"),  # before: "wheel_radius: ..." alone, no file
    ],
)  # fmt: skip
def test_a_users_robot_config_that_raises_is_bad_input_naming_the_file_the_model_and_the_class(
    fresh, capsys, cls, says
):
    """Before: exit 3, "internal error ... This is a bug" (or a message naming neither file nor robot)."""
    (fresh / "hostile_robots.py").write_text(HOSTILE_ROBOTS)
    text = (HERE.parent / "configs" / "unicycle_parking.yaml").read_text()
    path = fresh / "hostile.yaml"
    path.write_text(text.replace("  model: unicycle", f"  model: hostile_robots:{cls}", 1))
    with pytest.raises(ConfigError, match=re.escape(f"{path}: {says}")):
        load_config(path)
    from ilc_steering.cli import main

    assert main(["run", str(path), "--trials", "1", "--hold", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ilc-steering: config error: ") and says in err and len(err.splitlines()) == 1


def test_a_run_of_a_users_robot_is_saved_as_its_module_and_loads_back_in_another_process(fresh, capsys):
    """``run --json`` of ``plant.model: module:Class`` keeps the entry, so ``plot`` reads it where no
    config registered the name (before: "plant.model: must be one of [...], got 'my_unicycle'")."""
    from ilc_steering.cli import main
    from ilc_steering.plots import load_run

    (fresh / "my_unicycle.py").write_text(
        "from dataclasses import dataclass\nfrom typing import Literal\n"
        "from ilc_steering.core.robots.unicycle import UnicyclePlantConfig\n\n\n"
        "@dataclass(frozen=True)\nclass Config(UnicyclePlantConfig):\n"
        '    model: Literal["my_unicycle"]  # type: ignore[assignment]\n'
    )
    text = (HERE.parent / "configs" / "unicycle_parking.yaml").read_text()
    path, out = fresh / "mine.yaml", fresh / "run.json"
    path.write_text(text.replace("  model: unicycle", "  model: my_unicycle:Config", 1))
    main(["run", str(path), "--trials", "2", "--hold", "2", "--json", str(out)])
    assert json.loads(out.read_text())["config"]["plant"]["model"] == "my_unicycle:Config"
    for state in (robots.ROBOTS, robots._LOADED, robots._SOURCES):  # as a fresh process has them
        state.pop("my_unicycle", None)
    run = load_run(out)
    assert run.config == load_config(path) and run.config.plant.model == "my_unicycle"
    packaged = fresh / "packaged.json"
    main(["run", "unicycle_parking", "--trials", "1", "--hold", "1", "--json", str(packaged)])
    assert json.loads(packaged.read_text())["config"]["plant"]["model"] == "unicycle"  # a packaged name stays
