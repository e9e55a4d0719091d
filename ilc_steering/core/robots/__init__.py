"""The robots: one module each, one line of :data:`ROBOTS` each.

A robot's module owns everything about it: its maths (the map to chained form and back, the
input transformation), its plant class (:class:`~ilc_steering.core.plants.Plant`), its compiled
field with the named layout of what the field reads, its chart test, its drawing outline, its
reference field for ``solve_ivp``, and its config keys: a frozen dataclass, its ``plant.model``
literal the registry's name, whose ``plant()`` and ``nominal_map()`` build the rest. The config,
the simulator, rendering, costs, sweep and compare reach a robot only through this table and
those objects; nothing outside a robot's module asks what kind of robot it is.

Adding a robot: write its module (``docs/robots.md`` walks through one), then one line: in the
package that holds it, an entry point ``name = "package.module:ConfigClass"`` in the group
``ilc_steering.robots`` (``[project.entry-points."ilc_steering.robots"]`` of its
``pyproject.toml``), which every process finds (the CLI's, a comparison's workers); or, in a
script, ``register("name", "package.module:ConfigClass")`` before its first config is loaded. The
entries are strings, loaded on first use, so importing this package imports no robot. A config
may also name the class itself, ``plant: {model: "package.module:ConfigClass"}``, as ``--learner``
takes ``module:attr``: it is registered under its ``model`` literal when the config loads.

Plugins are isolated (``docs/trust.md``): an installed entry point is only a string until a
config names its robot, so a plugin whose module raises, does not parse or names something that
is not a robot config breaks only the commands that use it, and those with a one-line error
naming the package and the entry point. An entry point with a malformed name or value, or one
that names a packaged robot (``car``) or a robot another package names, is skipped with a
one-line warning on stderr: a packaged name is never replaced. A config class is checked against
the :class:`~ilc_steering.core.plants.PlantConfig` protocol (and its plant class against
:class:`~ilc_steering.core.plants.Plant`) when it is first loaded; a missing method is named.

**The robot's side.** What a robot's own program computes to steer by the chained inputs ``v1,
v2`` a trial sends (``docs/your_robot.md``): one function per packaged robot, re-exported here
from its module and loaded on first use (``docs/modelling.md`` writes the maps out):
:func:`car_inputs` (eqs. 4-5, ``car_model.chained_inputs``), :func:`unicycle_inputs` and
:func:`trailer_inputs`.
"""

from __future__ import annotations

import dataclasses
import sys
import typing
from importlib import import_module
from typing import Any

from ilc_steering.entries import PLUGIN_ENTRY, PLUGIN_NAME, load_entry, read_plugins
from ilc_steering.errors import BadInput

__all__ = [
    "ENTRY",
    "GROUP",
    "PACKAGED",
    "ROBOTS",
    "car_inputs",
    "check_robot",
    "config_class",
    "model_name",
    "names",
    "nominal_plant",
    "register",
    "saved_name",
    "skipped",
    "trailer_inputs",
    "unicycle_inputs",
]

_INPUTS = {
    "car_inputs": ("ilc_steering.core.robots.car_model", "chained_inputs"),
    "unicycle_inputs": ("ilc_steering.core.robots.unicycle", "unicycle_inputs"),
    "trailer_inputs": ("ilc_steering.core.robots.car_trailer", "trailer_inputs"),
}
"""The robot's side, by its public name here: ``(module, name in it)``, imported on first use (the
unicycle's and the trailer's modules load numba)."""

ROBOTS: dict[str, str] = {
    "car": "ilc_steering.core.robots.car:CarPlantConfig",
    "chained": "ilc_steering.core.robots.chained:ChainedPlantConfig",
    "unicycle": "ilc_steering.core.robots.unicycle:UnicyclePlantConfig",
    "car_trailer": "ilc_steering.core.robots.car_trailer:TrailerPlantConfig",
    "process": "ilc_steering.core.robots.process:ProcessPlantConfig",
}
"""``plant.model`` -> ``"module:ConfigClass"`` of the robot's config keys: the core's robots. The
plants that live on a higher floor (highway-env's car in ``envs/highway_plant.py``) are the library's own
entry points in :data:`GROUP`, like any installed package's, so the core names nothing above it."""

PACKAGED = frozenset(ROBOTS)
"""The robots that ship with the library: no plugin replaces them."""

_NAME = PLUGIN_NAME
ENTRY = PLUGIN_ENTRY
"""A ``"package.module:ConfigClass"`` entry (also accepted as ``plant.model`` itself)."""
_LOADED: dict[str, Any] = {}
_PLUGINS: list[bool] = []  # whether the installed packages' entry points were read
_SOURCES: dict[str, str] = {}  # robot name -> the package and entry point that registered it
_SKIPPED: dict[str, str] = {}  # "package: name = value" -> why the entry point was skipped
GROUP = "ilc_steering.robots"
"""The entry-point group in which an installed package names its robots."""

CONFIG_METHODS = ("plant", "nominal_map", "check_task")
"""What a robot's config class must provide besides ``model``, ``kind``, ``plant_class``,
``dimension`` and ``steering_limit`` (:class:`~ilc_steering.core.plants.PlantConfig`)."""
PLANT_METHODS = (
    "nominal_plant", "configuration", "estimate", "check_configuration", "initial_state", "kernel",
    "with_true_factors", "true_factors", "family_names", "with_family", "reference_field",
)  # fmt: skip
"""What a robot's plant class must provide (:class:`~ilc_steering.core.plants.Plant`)."""
EXTERNAL_METHODS = (
    "configuration", "estimate", "check_configuration", "initial_state", "with_frame", "run_trials", "reseed",
)  # fmt: skip
"""What a plant that runs its own trials must provide instead
(:class:`~ilc_steering.core.external.ExternalPlant`: someone else's simulator or a real robot)."""


def register(name: str, entry: str) -> None:
    """Make robot ``name`` (its ``plant.model``) known: ``entry`` is ``"module:ConfigClass"``.
    Registering a name again with the same entry is a no-op; with another, an error."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise BadInput(
            f"a robot's name is 1-40 lower-case letters, digits or '_', starting with a letter; got {name!r}"
        )
    if not isinstance(entry, str) or not ENTRY.fullmatch(entry):
        raise BadInput(f"a robot's entry is 'package.module:ConfigClass', got {entry!r}")
    if ROBOTS.get(name, entry) != entry:
        raise BadInput(f"robot {name!r} is registered already, as {ROBOTS[name]!r}")
    ROBOTS[name] = entry


def names() -> list[str]:
    """Every registered ``plant.model``, in the order they were registered (the packaged robots,
    then the installed packages' entry points)."""
    _read_plugins()
    return list(ROBOTS)


def saved_name(name: str) -> str:
    """``plant.model`` as a record on disk (``run --json``) keeps robot ``name``: the name itself if
    every process knows it (a packaged robot, an installed package's entry point), else the
    ``"module:ConfigClass"`` it was registered from (a config's ``plant.model: module:ConfigClass``,
    a script's :func:`register`), which loads it back in another process."""
    if name in PACKAGED or name not in ROBOTS or _SOURCES.get(name, "").startswith("package "):
        return name
    return ROBOTS[name]


def skipped() -> dict[str, str]:
    """The installed entry points that were skipped (``"package: name = value"``), with the reason."""
    _read_plugins()
    return dict(_SKIPPED)


def _skip(where: str, reason: str) -> None:
    _SKIPPED[where] = reason
    print(f"ilc-steering: warning: robot plugin {where}: {reason}; skipped", file=sys.stderr)


def _read_plugins() -> None:
    """Register the robots the installed packages name in :data:`GROUP`, once per process
    (:func:`~ilc_steering.entries.read_plugins`: strings only, nothing is imported); one that a
    script registered under another entry first is skipped too."""
    if _PLUGINS:
        return
    _PLUGINS.append(True)
    plugins, skipped = read_plugins(GROUP, "robot", {name: ROBOTS[name] for name in PACKAGED}, "a packaged robot")
    _SKIPPED.update(skipped)
    for plugin in plugins:
        if plugin.name in PACKAGED:
            continue
        if ROBOTS.get(plugin.name, plugin.entry) != plugin.entry:
            _skip(plugin.where, f"{plugin.name!r} is registered already, by {_source(plugin.name)}")
            continue
        register(plugin.name, plugin.entry)
        _SOURCES[plugin.name] = f"package {plugin.package}, entry point {plugin.name} = {plugin.entry}"


def _source(name: str) -> str:
    return _SOURCES.get(name, f"entry {ROBOTS[name]!r}")


def config_class(name: str, folders: tuple[str, ...] = ()) -> Any:
    """The config class of robot ``name`` (or of ``"module:ConfigClass"``, registered under its
    ``model`` literal, its module found as :func:`~ilc_steering.entries.load_entry` finds one: the
    working directory and ``folders``, the config's folder, searched last), its module imported on
    first use and checked against the protocol;
    ``ValueError`` naming the robot and the package or entry that provides it."""
    if isinstance(name, str) and ENTRY.fullmatch(name):
        return _from_entry(name, folders)
    _read_plugins()  # once per process; a plugin that conflicts is reported whatever is asked for
    if name not in ROBOTS:
        raise BadInput(f"no robot is registered as {name!r}; registered: {names()}")
    if name not in _LOADED:
        _LOADED[name] = _load(ROBOTS[name], f"robot {name!r} ({_source(name)})", name)
    return _LOADED[name]


def _from_entry(entry: str, folders: tuple[str, ...] = ()) -> Any:
    """The config class an entry names, registered under its ``model`` literal."""
    cls = load_entry(entry, "robot", folders, example="ConfigClass")  # named under the config's plant.model
    check_robot(cls, f"robot {entry}")
    name = model_name(cls)
    register(name, entry)  # a packaged name or another robot's is refused here
    _SOURCES.setdefault(name, f"entry {entry!r}")
    _LOADED.setdefault(name, cls)
    return cls


def _load(entry: str, who: str, name: str | None, folders: tuple[str, ...] = ()) -> Any:
    """Import ``entry``, isolated: whatever the module raises is a one-line ``ValueError`` naming ``who``."""
    cls = load_entry(entry, who, folders, example="ConfigClass")
    check_robot(cls, who, name)
    return cls


def model_name(cls: Any) -> str:
    hints = typing.get_type_hints(cls) if isinstance(cls, type) else {}
    literal = typing.get_args(hints.get("model"))
    return str(literal[0]) if len(literal) == 1 and isinstance(literal[0], str) else ""


def check_robot(cls: Any, who: str, name: str | None = None) -> None:
    """``ValueError`` naming ``who`` and what is missing unless ``cls`` is a robot's config class:
    a frozen dataclass with ``model: Literal[name]``, ``kind``, ``plant_class``, ``dimension``,
    ``steering_limit`` and :data:`CONFIG_METHODS`, whose plant class has :data:`PLANT_METHODS` (or,
    if it runs its own trials, :data:`EXTERNAL_METHODS`)."""
    what = getattr(cls, "__qualname__", repr(cls)[:80])
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise BadInput(f"{who}: {what} is not a robot's config class (a frozen dataclass; docs/robots.md)")
    if not cls.__dataclass_params__.frozen:  # type: ignore[attr-defined]
        raise BadInput(f"{who}: {what} must be a frozen dataclass (@dataclass(frozen=True))")
    try:
        model = model_name(cls)
    except Exception as error:
        raise BadInput(f"{who}: {what}: its type hints cannot be read ({type(error).__name__}: {error})") from None
    if not model or (name is not None and model != name):
        wanted = f'Literal["{name}"]' if name else 'Literal["<name>"]'
        raise BadInput(f"{who}: {what} needs a field model: {wanted} (its registered name; docs/robots.md)")
    for attribute in ("kind", "plant_class", "dimension", "steering_limit", *CONFIG_METHODS):
        if not hasattr(cls, attribute) and attribute not in {f.name for f in dataclasses.fields(cls)}:
            raise BadInput(f"{who}: {what} has no {attribute!r} (the PlantConfig protocol, docs/robots.md)")
    plant: Any = getattr(cls, "plant_class")  # noqa: B009  (a class that passed the checks above)
    external = callable(getattr(plant, "run_trials", None))
    protocol = "the ExternalPlant protocol" if external else "the Plant protocol"
    for attribute in EXTERNAL_METHODS if external else PLANT_METHODS:
        if not callable(getattr(plant, attribute, None)):
            where = getattr(plant, "__qualname__", repr(plant)[:80])
            raise BadInput(f"{who}: its plant class {where} has no method {attribute!r} ({protocol})")


def nominal_plant(chained_map: Any, dimension: int, steering_limit: float | None = None) -> Any:
    """The plant the controller assumes: the robot of ``chained_map`` (its ``robot`` names it) with
    its true geometry the nominal one, of chained dimension ``dimension``."""
    plant_class = config_class(chained_map.robot).plant_class
    return plant_class.nominal_plant(chained_map, dimension, steering_limit)


def __getattr__(name: str) -> Any:
    if name in _INPUTS:
        module, attribute = _INPUTS[name]
        return getattr(import_module(module), attribute)
    raise AttributeError(f"module 'ilc_steering.core.robots' has no attribute {name!r}")
