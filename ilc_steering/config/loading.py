"""Loading a scenario: a YAML file or a packaged config through the one YAML reader
(:mod:`ilc_steering.yaml_reader`) and the schemas (:mod:`ilc_steering.schema`); a robot's module
named by ``plant.model: module:ConfigClass`` is found beside the config too."""

from __future__ import annotations

import dataclasses
import os
import re
import stat
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic_core import core_schema

from ilc_steering.config.sections import LearningConfig, SimulationConfig, Task, domain, require
from ilc_steering.config.steering import SteeringConfig, robots_code
from ilc_steering.core import robots
from ilc_steering.core.plants import PlantConfig
from ilc_steering.entries import CONFIG_FOLDERS
from ilc_steering.errors import ConfigError
from ilc_steering.readers import check_depth, read_text
from ilc_steering.schema import show, validate
from ilc_steering.yaml_reader import MAX_VALUES, count_values, load_yaml

__all__ = [
    "MAX_FILE_BYTES",
    "ConfigSource",
    "config_data",
    "load_config",
    "packaged_configs",
    "plant_config",
    "resolve_config",
]

MAX_FILE_BYTES = 1 << 20
"""Largest config file read [bytes]."""

_FOLDERS = CONFIG_FOLDERS
"""The folder of the config being loaded, searched for a robot's module it names."""


def packaged_configs() -> list[str]:
    """Names of the configs shipped in ``ilc_steering.configs``."""
    root = resources.files("ilc_steering.configs")
    return sorted(p.name.removesuffix(".yaml") for p in root.iterdir() if p.name.endswith(".yaml"))


@dataclass(frozen=True)
class ConfigSource:
    """A config as a command names it, resolved once, at the start, to what it names: its text, read
    then. Everything after (a session's copy, a sweep's workers, a run's record) takes this, never
    the name again: a folder of the same name made later (``sweep NAME --out NAME``) changes nothing."""

    text: str
    """The YAML."""
    origin: str
    """How messages name it: its path, or ``NAME.yaml (packaged)``."""
    path: Path | None
    """The file it was read from (an input of the command, which no output may be); the packaged
    config's own file where the package is on disk."""
    folder: str | None
    """The folder a robot's module beside it is found in, and a program it names runs in; ``None``
    for a packaged config."""


def _is_regular(path: Path) -> bool | None:
    """Whether ``path`` is a regular file (links followed); ``None`` when nothing is there at all."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except FileNotFoundError:
        return None if not os.path.islink(path) else False  # a dangling link is there: reading it says so
    except (OSError, ValueError):
        return False  # a loop of links, a name too long, a NUL: reading it names the problem


def resolve_config(source: str | Path) -> ConfigSource:
    """What the config ``source`` names, read now: a YAML file, or a packaged config by its bare name
    (``forward_parking``), unless a regular file of that name is in the working directory. A folder
    named like a packaged config is not a config: the name is the packaged one's."""
    text = str(source)
    path = Path(source)
    bare = re.fullmatch(r"[A-Za-z0-9_\-]+", text) is not None
    resource = resources.files("ilc_steering.configs") / f"{text}.yaml" if bare else None
    here = _is_regular(path)
    if resource is not None and resource.is_file() and not here:
        origin = f"{text}.yaml (packaged)"
        return ConfigSource(resource.read_text(encoding="utf-8"), origin, Path(str(resource)), None)
    if here is None and path.suffix not in (".yaml", ".yml"):
        raise ConfigError(f"{text!r} is neither a YAML file nor a packaged config; packaged: {packaged_configs()}")
    if here is None:
        raise ConfigError(f"{path}: no such config file")
    try:
        content = read_text(path, MAX_FILE_BYTES)
    except ValueError as error:
        raise ConfigError(str(error)) from None
    return ConfigSource(content, str(path), path, str(path.parent))


def load_config(source: str | Path | ConfigSource | SteeringConfig | dict[str, Any]) -> SteeringConfig:
    """A scenario from a YAML path, a packaged config name (``"forward_parking"``, see
    :func:`resolve_config`), a config resolved before, a mapping, or an already built config
    (returned as is)."""
    if isinstance(source, SteeringConfig):
        return source
    if not isinstance(source, (str, Path, ConfigSource, dict)):
        raise ConfigError(
            f"config must be a YAML path, a packaged config name, a mapping or a SteeringConfig, got {show(source)}"
        )
    folders: tuple[str, ...] = ()
    if isinstance(source, dict):
        data, origin = source, "<mapping>"
        if count_values(data) > MAX_VALUES:
            raise ConfigError(f"{origin}: more than {MAX_VALUES} values; not a config")
        try:
            check_depth(data, origin)
        except ValueError as error:
            raise ConfigError(f"{error}; not a config") from None
    else:
        found = source if isinstance(source, ConfigSource) else resolve_config(source)
        data, origin = load_yaml(found.text, found.origin), found.origin
        folders = () if found.folder is None else (found.folder,)
    token = _FOLDERS.set(folders)  # a robot's module beside its config is found (entries.load_entry)
    try:
        return _config(data)
    except ConfigError as error:
        raise ConfigError(f"{origin}: {error}") from None
    finally:
        _FOLDERS.reset(token)


def config_data(config: SteeringConfig) -> dict[str, Any]:
    """``config`` as plain data that :func:`load_config` builds back, in another process too (a run's
    JSON, which ``plot`` reads): a robot of a user's module is saved as the ``module:ConfigClass``
    it was loaded from, not as the name only this process registered (:func:`robots.saved_name`)."""
    data = dataclasses.asdict(config)
    _save_models(config.plant, data["plant"])
    return data


def _save_models(plant: Any, data: dict[str, Any]) -> None:
    """Put each robot's saved name (:func:`robots.saved_name`) in ``data``, ``plant``'s fields as
    :func:`dataclasses.asdict` made them, a robot config nested in another's included."""
    data["model"] = robots.saved_name(plant.model)
    for field in dataclasses.fields(plant):
        inner = getattr(plant, field.name)
        if isinstance(inner, PlantConfig) and isinstance(data.get(field.name), dict):
            _save_models(inner, data[field.name])


def _config(data: Any) -> SteeringConfig:
    """A :class:`SteeringConfig` from a file's data: each section through its schema
    (:func:`~ilc_steering.schema.validate`), the plant's by its robot's config class, then the
    cross-key checks of ``SteeringConfig.__post_init__``."""
    require(isinstance(data, dict), "config", f"must be a mapping, got {show(data)}")
    allowed = sorted(f.name for f in dataclasses.fields(SteeringConfig))
    unknown = sorted(map(str, set(data) - set(allowed)))
    require(not unknown, unknown[0] if unknown else "", f"unknown key; allowed keys here: {allowed}")

    def section(key: str) -> Any:  # the sections in the order of the fields, each checked as it enters
        require(key in data, key, "missing required key")
        return data[key]

    name = section("name")
    require(isinstance(name, str), "name", f"must be a string, got {show(name)}")
    plant = plant_config(section("plant"), "plant")
    task = validate(Task, section("task"), "task")
    learning = validate(LearningConfig, section("learning"), "learning")
    simulation = validate(SimulationConfig, data.get("simulation", {}), "simulation")
    return SteeringConfig(name, plant, task, learning, simulation)


def plant_config(value: Any, key: str = "plant") -> PlantConfig:
    """A robot's config keys from a file's data, under ``key``: ``model`` names a registered robot
    or is ``"package.module:ConfigClass"`` (its module found beside the config too), and the
    robot's config class is its schema."""
    require(isinstance(value, dict), key, f"must be a mapping, got {show(value)}")
    model = value.get("model")
    if isinstance(model, str) and robots.ENTRY.fullmatch(model):  # "package.module:ConfigClass", as --learner
        with domain(f"{key}.model"):
            cls = robots.config_class(model, _FOLDERS.get())
        value = {**value, "model": robots.model_name(cls)}
    else:
        known = robots.names()
        require(
            isinstance(model, str) and model in known,
            f"{key}.model",
            f"must be one of {known} or 'package.module:ConfigClass', got {show(model)}",
        )
        with domain(f"{key}.model"):  # a plugin that cannot load is named, with its package
            cls = robots.config_class(model)
    with robots_code(cls, "", model):  # its __post_init__ is the user's code when the robot is theirs
        built: PlantConfig = validate(cls, value, key)
    return built


def _nested_plant(value: Any) -> PlantConfig:
    try:
        return plant_config(value, "")
    except ConfigError as error:  # "key: problem" relative to the field, which pydantic names
        raise ConfigError(str(error).removeprefix(": ")) from None


# A field typed PlantConfig inside a robot's config (a robot that wraps another, e.g. a program
# whose nominal model is a car) is read as a whole robot config.
setattr(  # noqa: B010  (the core's protocol learns its schema here, on the floor that owns schemas)
    PlantConfig,
    "__get_pydantic_core_schema__",
    classmethod(lambda cls, source, handler: core_schema.no_info_plain_validator_function(_nested_plant)),
)
