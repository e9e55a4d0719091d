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
entries are strings, loaded on first use, so importing this package imports no robot.
"""

from __future__ import annotations

import re
from importlib import import_module
from importlib.metadata import entry_points
from typing import Any

__all__ = ["ROBOTS", "config_class", "names", "nominal_plant", "register"]

ROBOTS: dict[str, str] = {
    "car": "ilc_steering.core.robots.car:CarPlantConfig",
    "chained": "ilc_steering.core.robots.chained:ChainedPlantConfig",
    "unicycle": "ilc_steering.core.robots.unicycle:UnicyclePlantConfig",
    "car_trailer": "ilc_steering.core.robots.car_trailer:TrailerPlantConfig",
    "highway_parking": "ilc_steering.envs.highway:HighwayPlantConfig",  # an external plant (extra [highway])
}
"""``plant.model`` -> ``"module:ConfigClass"`` of the robot's config keys."""

_NAME = re.compile(r"[a-z][a-z0-9_]{0,39}")
_ENTRY = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_]\w*")
_LOADED: dict[str, Any] = {}
_PLUGINS: list[bool] = []  # whether the installed packages' entry points were read
GROUP = "ilc_steering.robots"
"""The entry-point group in which an installed package names its robots."""


def register(name: str, entry: str) -> None:
    """Make robot ``name`` (its ``plant.model``) known: ``entry`` is ``"module:ConfigClass"``.
    Registering a name again with the same entry is a no-op; with another, an error."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ValueError(
            f"a robot's name is 1-40 lower-case letters, digits or '_', starting with a letter; got {name!r}"
        )
    if not isinstance(entry, str) or not _ENTRY.fullmatch(entry):
        raise ValueError(f"a robot's entry is 'package.module:ConfigClass', got {entry!r}")
    if ROBOTS.get(name, entry) != entry:
        raise ValueError(f"robot {name!r} is registered already, as {ROBOTS[name]!r}")
    ROBOTS[name] = entry


def names() -> list[str]:
    """Every registered ``plant.model``, in the order they were registered (the packaged robots,
    then the installed packages' entry points)."""
    _read_plugins()
    return list(ROBOTS)


def _read_plugins() -> None:
    """Register the robots the installed packages name in :data:`GROUP`, once per process."""
    if _PLUGINS:
        return
    _PLUGINS.append(True)
    for point in entry_points(group=GROUP):
        register(point.name, point.value)


def config_class(name: str) -> Any:
    """The config class of robot ``name``, its module imported on first use."""
    if name not in ROBOTS:
        _read_plugins()
    if name not in ROBOTS:
        raise ValueError(f"no robot is registered as {name!r}; registered: {names()}")
    if name not in _LOADED:
        module, attribute = ROBOTS[name].split(":")
        try:
            cls = getattr(import_module(module), attribute)
        except (ImportError, AttributeError) as error:
            raise ValueError(f"robot {name!r}: cannot load {ROBOTS[name]!r}: {error}") from None
        _LOADED[name] = cls
    return _LOADED[name]


def nominal_plant(chained_map: Any, dimension: int, steering_limit: float | None = None) -> Any:
    """The plant the controller assumes: the robot of ``chained_map`` (its ``robot`` names it) with
    its true geometry the nominal one, of chained dimension ``dimension``."""
    plant_class = config_class(chained_map.robot).plant_class
    return plant_class.nominal_plant(chained_map, dimension, steering_limit)
