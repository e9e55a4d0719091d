"""The one YAML reader of the library: configs and the RL hyperparameter files.

Strict where YAML 1.1 (PyYAML) and a reader disagree: a number with a leading zero (``010``, octal
8 to YAML 1.1, 10 to YAML 1.2), a sexagesimal one (``1:30``, 90 to YAML 1.1) and one with an
underscore (``0.0_2``, 0.002 to YAML 1.1, text to YAML 1.2) are kept as their text, marked
:class:`Ambiguous`, for the schema to refuse under a numeric key with both readings; ``1e-3`` is
the number it looks like (YAML 1.1 reads it as text). Safe types only, merge keys
(``<<: *defaults``) honoured, a key given twice refused, at most :data:`MAX_VALUES` values
(aliases expanded) and :data:`~ilc_steering.readers.MAX_DEPTH` levels.
"""

from __future__ import annotations

import re
from typing import Any

from ilc_steering.errors import ConfigError
from ilc_steering.readers import MAX_DEPTH, check_depth

__all__ = ["MAX_VALUES", "Ambiguous", "count_values", "load_yaml"]

MAX_VALUES = 100_000
"""Most values (mapping entries and list items, aliases expanded) a YAML document may hold."""
_LEADING_ZERO = re.compile(r"[-+]?0[0-9_]+")
EXPONENT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")
"""A number in exponent form without a dot (``1e-3``), which YAML 1.1 reads as text."""


class Ambiguous(str):
    """A YAML scalar that YAML 1.1 reads as a number other than the one its text shows (``010``,
    ``1:30``) or that YAML 1.2 reads as text (``1_0``, ``0.0_2``): kept as its text, refused by
    the schema (:mod:`ilc_steering.schema`) under a numeric key, with both readings."""

    reading: str = ""


_LEADING_ZERO = re.compile(r"[-+]?0[0-9_]+")


def count_values(data: Any) -> int:
    """The number of values in ``data`` with aliases expanded, counting no further than :data:`MAX_VALUES`."""
    count, todo = 0, [data]
    while todo and count <= MAX_VALUES:
        item = todo.pop()
        if isinstance(item, dict):
            count += len(item)
            todo.extend(item.values())
        elif isinstance(item, list):
            count += len(item)
            todo.extend(item)
    return count


def _strict_number(kind: str) -> Any:
    """A constructor of YAML 1.1 ``int`` or ``float`` scalars that keeps a leading-zero or
    sexagesimal one as :class:`Ambiguous` text."""
    import yaml

    base = yaml.SafeLoader.yaml_constructors[f"tag:yaml.org,2002:{kind}"]

    def construct(loader: Any, node: Any) -> Any:
        text = str(node.value)
        number = base(loader, node)
        if ":" in text or "_" in text or _LEADING_ZERO.fullmatch(text):  # YAML 1.2 reads 1_0 and 0.0_2 as text
            marked = Ambiguous(text)
            marked.reading = f"{number:g}" if isinstance(number, float) else str(number)
            return marked
        return number

    return construct


def _depth(data: Any, origin: str) -> None:
    try:
        check_depth(data, origin)
    except ValueError as error:
        raise ConfigError(f"{error}; not a config") from None


def load_yaml(text: str, origin: str) -> Any:
    """Parse a config's YAML: safe types only, merge keys, no duplicate keys, integers read strictly,
    at most :data:`MAX_VALUES` values and :data:`~ilc_steering.readers.MAX_DEPTH` levels."""
    import yaml

    merge = "tag:yaml.org,2002:merge"

    class Loader(yaml.SafeLoader):
        def construct_mapping(self, node: Any, deep: bool = False) -> Any:
            # a key given twice is a typo; a key a merge (<<) brings and the mapping overrides is not
            keys = [self.construct_object(k, deep=deep) for k, _ in node.value if k.tag != merge]
            duplicated = sorted({str(k) for k in keys if keys.count(k) > 1})
            if duplicated:
                line = node.start_mark.line + 1
                raise ConfigError(f"{origin}: duplicate key {duplicated[0]!r} in the mapping at line {line}")
            return super().construct_mapping(node, deep=deep)

    Loader.add_constructor("tag:yaml.org,2002:int", _strict_number("int"))
    Loader.add_constructor("tag:yaml.org,2002:float", _strict_number("float"))
    Loader.add_implicit_resolver("tag:yaml.org,2002:float", EXPONENT, list("-+0123456789."))
    try:
        data = yaml.load(text, Loader=Loader)
    except RecursionError:
        raise ConfigError(f"{origin}: nested deeper than {MAX_DEPTH} levels; not a config") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise ConfigError(f"{origin}: not valid YAML{where}: {problem}") from None
    if count_values(data) > MAX_VALUES:
        raise ConfigError(f"{origin}: more than {MAX_VALUES} values (anchors and aliases expanded); not a config")
    _depth(data, origin)
    return data
