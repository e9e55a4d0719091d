"""Code named by a string ``module:attr``: a robot's config class, a learner's factory, a plugin.

One loader, one search rule and one plugin reader for all of them, on the lowest floor so that
every floor uses it:

- ``module`` is an import name (``my_robot``, ``mypkg.mod``), ``attr`` a name in it, dotted for a
  nested one (``module:Class.make``, as in an entry point);
- a user's module is found on the path, then in the **working directory**, then in the **folder
  of the config** that names it (both appended to ``sys.path``, last, so that they shadow nothing
  installed; spawned workers inherit the path);
- whatever goes wrong (not of that form, a file's path given, the module does not import or its
  own code raises, no such attribute) is a one-line ``ValueError`` that starts with ``who`` (the
  option or config key that named it) and says what to give instead: the user's code is named,
  never the library's;
- an installed package names its robots and learners in an entry-point group
  (:func:`read_plugins`): read as strings (nothing is imported until a name is asked for), each
  checked for its form and against the names the library owns and other packages' names; one
  that fails is skipped with a one-line warning on stderr that names the package.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Iterable, Mapping
from contextvars import ContextVar
from dataclasses import dataclass
from importlib import import_module, invalidate_caches
from importlib.metadata import entry_points
from pathlib import Path
from types import ModuleType
from typing import Any

from ilc_steering.errors import INTERRUPTS, BadInput

__all__ = [
    "CONFIG_FOLDERS",
    "ENTRY",
    "PLUGIN_ENTRY",
    "PLUGIN_NAME",
    "Plugin",
    "load_entry",
    "read_plugins",
    "search_folders",
]

CONFIG_FOLDERS: ContextVar[tuple[str, ...]] = ContextVar("CONFIG_FOLDERS", default=())
"""The folder of the config being loaded (empty for a packaged config or a mapping), set while it
is built: a robot's module beside it is found there, and a program it names runs there."""

ENTRY = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_][\w.]*")
"""The form of an entry: ``module:attr``, both dotted names."""
PLUGIN_NAME = re.compile(r"[a-z][a-z0-9_]{0,39}")
"""A plugin's name (an entry point's): 1-40 lower-case letters, digits or '_', starting with a letter."""
PLUGIN_ENTRY = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_]\w*")
"""A plugin's value: ``package.module:attr``."""


@dataclass(frozen=True)
class Plugin:
    """An entry point an installed package names: ``name = entry``, of distribution ``package``."""

    name: str
    entry: str
    package: str

    @property
    def where(self) -> str:
        """``"package: name = entry"``, as a warning names it."""
        return f"{self.package}: {self.name} = {self.entry}"


def read_plugins(group: str, kind: str, owned: Mapping[str, str], owner: str) -> tuple[list[Plugin], dict[str, str]]:
    """The entry points the installed packages name in ``group`` (strings only: nothing is
    imported), and the ones skipped (``"package: name = entry"`` -> why), each skipped one warned
    on stderr in one line that names the package and ``kind`` (``"robot"``). Skipped: a name not of
    :data:`PLUGIN_NAME` or a value not of :data:`PLUGIN_ENTRY`; a name of ``owned`` (the library's
    own names -> their entries; ``owner`` says what they are, ``"a packaged robot"``) with another
    entry (with the same entry it is the library's own, taken silently as it is); a name an earlier
    package names with another entry. Unreadable metadata skips the group, with a warning."""
    skipped: dict[str, str] = {}

    def skip(where: str, reason: str) -> None:
        skipped[where] = reason
        print(f"ilc-steering: warning: {kind} plugin {where}: {reason}; skipped", file=sys.stderr)

    try:
        points = list(entry_points(group=group))
    except Exception as error:  # a broken distribution's metadata must not break the library
        skip("(installed metadata)", f"cannot be read ({type(error).__name__}: {error})")
        return [], skipped
    found: dict[str, Plugin] = {}
    for point in points:
        plugin = Plugin(
            point.name, point.value, getattr(getattr(point, "dist", None), "name", None) or "an unknown package"
        )
        if not PLUGIN_NAME.fullmatch(plugin.name) or not PLUGIN_ENTRY.fullmatch(plugin.entry):
            skip(
                plugin.where,
                f"a {kind}'s entry point is name = 'package.module:attr', its name 1-40 lower-case "
                "letters, digits or '_', starting with a letter",
            )
        elif plugin.name in owned:
            if owned[plugin.name] != plugin.entry:
                skip(plugin.where, f"{plugin.name!r} is {owner}, which a plugin cannot replace")
        elif found.get(plugin.name, plugin).entry != plugin.entry:
            skip(plugin.where, f"{plugin.name!r} is named already, by package {found[plugin.name].package}")
        else:
            found.setdefault(plugin.name, plugin)
    return list(found.values()), skipped


def search_folders(folders: Iterable[str | os.PathLike[str]] = ()) -> None:
    """Put the working directory, then each of ``folders`` (a config's folder), on ``sys.path``,
    last, where a user's module beside them is found and nothing installed is shadowed."""
    for folder in (os.getcwd(), *(os.fspath(Path(f).resolve()) for f in folders)):
        if folder not in sys.path and not (folder == os.getcwd() and "" in sys.path):
            sys.path.append(folder)


def load_entry(entry: str, who: str, folders: Iterable[str | os.PathLike[str]] = (), example: str = "make") -> Any:
    """The object ``entry`` (``module:attr``) names, its module imported now, the working directory
    and ``folders`` searched last (:func:`search_folders`). ``ValueError`` starting with ``who`` if
    it is not of that form (``example`` is the attribute the message suggests), cannot be imported
    (the module's own code raised, named as such) or has no such attribute."""
    if not isinstance(entry, str):
        raise BadInput(f"{who}: give module:attr as a string, got {type(entry).__name__}")
    module_name, colon, attr = entry.partition(":")
    if module_name.endswith(".py") or "/" in module_name or "\\" in module_name:
        stem = module_name.replace("\\", "/").rsplit("/", 1)[-1].removesuffix(".py")
        raise BadInput(
            f"{who} {entry}: give the module's import name, not its file: {stem}:{attr or example} "
            f"for {stem}.py in the working directory or the config's folder (or a package's dotted name)"
        )
    if (
        not colon
        or not ENTRY.fullmatch(entry)
        or not all(p.isidentifier() for p in (*module_name.split("."), *attr.split(".")))
    ):
        raise BadInput(
            f"{who} {entry}: give module:attr, a module's import name and a name in it, e.g. my_module:{example}"
        )
    folders = list(folders)
    search_folders(folders)
    invalidate_caches()  # a module written since this process started is found
    try:
        target: Any = import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name is not None and (module_name + ".").startswith(error.name + "."):
            where = ", ".join(
                [f"the working directory ({os.getcwd()})", *(f"the config's folder ({f})" for f in folders)]
            )
            raise BadInput(
                f"{who} {entry}: cannot import it: no module {error.name!r} in {where} or on the path"
            ) from None
        raise BadInput(f"{who} {entry}: cannot import it: importing it raised ModuleNotFoundError: {error}") from None
    except INTERRUPTS:
        raise
    except BaseException as error:  # the user's module: SyntaxError, its own error, even SystemExit
        problem = " ".join(str(error).split())[:300]
        raise BadInput(
            f"{who} {entry}: cannot import it: importing it raised {type(error).__name__}: {problem}"
        ) from None
    module = target
    for part in attr.split("."):
        if not hasattr(target, part):
            raise BadInput(f"{who} {entry}: cannot import it: {_missing(module, attr)}")
        target = getattr(target, part)
    return target


def _missing(module: ModuleType, attr: str) -> str:
    """That ``module`` (and its file) has no ``attr``, and, when an installed module of the same
    top-level name came before the working directory's file of that name (the working directory is
    searched last, so that it shadows nothing installed), so."""
    text = f"module {module.__name__} ({getattr(module, '__file__', None) or 'built in'}) has no attribute {attr!r}"
    top = module.__name__.split(".")[0]
    found = getattr(sys.modules.get(top), "__file__", None)
    for mine in (Path(top + ".py"), Path(top, "__init__.py")):
        if mine.is_file() and (found is None or Path(found).resolve() != mine.resolve()):
            return f"{text}; it is an installed module, found before your {mine} of the working directory: rename yours"
    return text
