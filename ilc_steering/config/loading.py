"""Loading a scenario: a YAML file or a packaged config through the one YAML reader
(:mod:`ilc_steering.yaml_reader`) and the schemas (:mod:`ilc_steering.schema`); a robot's module
named by ``plant.model: module:ConfigClass`` is found beside the config too."""

from __future__ import annotations

import dataclasses
import re
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

__all__ = ["MAX_FILE_BYTES", "config_data", "load_config", "packaged_configs", "plant_config"]

MAX_FILE_BYTES = 1 << 20
"""Largest config file read [bytes]."""

_FOLDERS = CONFIG_FOLDERS
"""The folder of the config being loaded, searched for a robot's module it names."""


def packaged_configs() -> list[str]:
    """Names of the configs shipped in ``ilc_steering.configs``."""
    root = resources.files("ilc_steering.configs")
    return sorted(p.name.removesuffix(".yaml") for p in root.iterdir() if p.name.endswith(".yaml"))


def _read(source: str | Path) -> tuple[Any, str]:
    path = Path(source)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if not path.is_file():
            raise ConfigError(f"{path}: no such config file")
        try:
            text = read_text(path, MAX_FILE_BYTES)
        except ValueError as error:
            raise ConfigError(str(error)) from None
        return load_yaml(text, str(path)), str(path)
    if not isinstance(source, str) or not re.fullmatch(r"[A-Za-z0-9_\-]+", source):
        raise ConfigError(f"{source!r} is neither a YAML file nor a packaged config; packaged: {packaged_configs()}")
    resource = resources.files("ilc_steering.configs") / f"{source}.yaml"
    if not resource.is_file():
        raise ConfigError(f"{source!r} is neither a YAML file nor a packaged config; packaged: {packaged_configs()}")
    origin = f"{source}.yaml (packaged)"
    return load_yaml(resource.read_text(encoding="utf-8"), origin), origin  # the package's own: small, UTF-8


def load_config(source: str | Path | SteeringConfig | dict[str, Any]) -> SteeringConfig:
    """A scenario from a YAML path, a packaged config name (``"forward_parking"``), a mapping,
    or an already built config (returned as is)."""
    if isinstance(source, SteeringConfig):
        return source
    if not isinstance(source, (str, Path, dict)):
        raise ConfigError(
            f"config must be a YAML path, a packaged config name, a mapping or a SteeringConfig, got {show(source)}"
        )
    data, origin = (source, "<mapping>") if isinstance(source, dict) else _read(source)
    if isinstance(source, dict):
        if count_values(data) > MAX_VALUES:
            raise ConfigError(f"{origin}: more than {MAX_VALUES} values; not a config")
        try:
            check_depth(data, origin)
        except ValueError as error:
            raise ConfigError(f"{error}; not a config") from None
    folders = (str(Path(source).parent),) if isinstance(source, (str, Path)) and Path(source).is_file() else ()
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
