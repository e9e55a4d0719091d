"""Configs and records checked by one schema library: pydantic v2, strict, unknown keys forbidden.

A config's sections, a robot's config keys (a user's frozen dataclass included) and the records
the library reads back are plain frozen dataclasses; :func:`validate` checks data read from a
file against one of them and builds it, or raises one :class:`~ilc_steering.errors.ConfigError`
naming the key. The data is checked as JSON is (pydantic's strict JSON mode), since it was read
from a file: a number is not a string, a bool is not a number, a list is a tuple of the declared
length, a ``Literal`` is one of its choices, every number is finite, a key not declared is refused,
and a missing one without a default is named. A dataclass's ``__post_init__`` then checks its
ranges; its :class:`~ilc_steering.errors.ConfigError` or
:class:`~ilc_steering.errors.ParameterError` is put under the key it came from.

Why pydantic rather than msgspec: msgspec ignores unknown fields of a standard dataclass (it
forbids them only on its own ``Struct``), and a user's robot config is a standard dataclass; pydantic
checks standard dataclasses with unknown keys forbidden and calls their ``__post_init__``.
"""

from __future__ import annotations

import dataclasses
import json
import reprlib
import types
import typing
from functools import cache
from typing import Annotated, Any

from pydantic import ConfigDict, StringConstraints, TypeAdapter, ValidationError

from ilc_steering.errors import BadInput, ConfigError, ParameterError
from ilc_steering.yaml_reader import Ambiguous

__all__ = ["NAME_PATTERN", "STRICT", "MethodName", "Name", "check_record", "validate"]

NAME_PATTERN = r"[A-Za-z0-9][A-Za-z0-9_.\-]{0,99}"
"""A name that names files: a config's ``name``, a scenario, a prior (1-100 letters, digits,
``_``, ``-`` or ``.``, starting with a letter or digit)."""
Name = Annotated[str, StringConstraints(pattern=f"^{NAME_PATTERN}$")]
"""A record's :data:`NAME_PATTERN` field: read back, a name that would lead a path elsewhere is refused."""
MethodName = Annotated[
    str, StringConstraints(pattern=r"^[A-Za-z0-9_][A-Za-z0-9_.]{0,99}(:[A-Za-z_][A-Za-z0-9_.]{0,99})?$")
]
"""A learner id of the registry, or a user's ``module:attr``."""

STRICT = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)
"""How every schema reads: strict types, no unknown key, finite numbers."""
TAGS = ("one-trial", "cyclic", "segmented")
"""The tags of a tagged union (a config's ``task``), left out of a key's name."""

_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlist, _REPR.maxdict, _REPR.maxlevel = 60, 60, 6, 4, 3


def show(value: Any) -> str:
    """A bounded ``repr`` for messages: a huge value (an alias bomb) must not cost its size."""
    return _REPR.repr(value)


def _strict(cls: Any, seen: set[int] | None = None) -> None:
    """Give every standard dataclass reachable from ``cls`` the :data:`STRICT` reading."""
    seen = set() if seen is None else seen
    if id(cls) in seen:
        return
    seen.add(id(cls))
    if dataclasses.is_dataclass(cls) and isinstance(cls, type):
        if "__pydantic_config__" not in cls.__dict__:
            cls.__pydantic_config__ = STRICT  # type: ignore[attr-defined]
        for hint in typing.get_type_hints(cls, include_extras=True).values():
            _strict(hint, seen)
    for argument in typing.get_args(cls):
        _strict(argument, seen)


@cache
def _adapter(cls: Any) -> TypeAdapter[Any]:
    _strict(cls)
    return TypeAdapter(cls)


def _plain(data: Any, loc: tuple[Any, ...], ambiguous: dict[tuple[Any, ...], Ambiguous]) -> Any:
    """``data`` as JSON holds it (tuples as lists), noting where a YAML scalar was ambiguous."""
    if isinstance(data, Ambiguous):
        ambiguous[loc] = data
        return str(data)
    if isinstance(data, dict):
        return {str(k): _plain(v, (*loc, str(k)), ambiguous) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [_plain(v, (*loc, i), ambiguous) for i, v in enumerate(data)]
    return data


def validate(cls: Any, data: Any, key: str = "", whole: str = "config") -> Any:
    """``cls`` (a frozen dataclass, or a type of them) built from ``data`` read from a file, or a
    :class:`~ilc_steering.errors.ConfigError` ``"key: problem"`` for the first thing wrong, its key
    under ``key`` (the section ``data`` was read from; ``""`` for a whole file, named ``whole``)."""
    ambiguous: dict[tuple[Any, ...], Ambiguous] = {}
    try:
        text = json.dumps(_plain(data, (), ambiguous), allow_nan=True)
    except (TypeError, ValueError) as error:  # a YAML date, a set: nothing JSON holds
        problem = f"holds a value that is not a number, a string, a list or a mapping ({error})"
        raise ConfigError(f"{key or whole}: {problem}") from None
    try:
        return _adapter(cls).validate_json(text)
    except ValidationError as errors:
        where, problem = _message(errors.errors()[0], cls, data, ambiguous)
        raise ConfigError(f"{_join(key, where) or whole}: {problem}") from None


def check_record(cls: Any, data: Any, path: Any, hint: str = "") -> Any:
    """``data``, a record read from the file ``path``, checked against its schema ``cls`` (a frozen
    dataclass) and built as it; ``ValueError`` ``"path: key: problem"`` (``; hint`` after it) for the
    first thing wrong: a wrong type, a missing key, an unknown key, a list of the wrong length."""
    try:
        return validate(cls, data, whole="the record")
    except ConfigError as error:
        raise BadInput(f"{path}: {error}" + (f"; {hint}" if hint else "")) from None


def _join(*keys: str) -> str:
    return ".".join(k for k in keys if k).replace(".[", "[")


def _key(loc: tuple[Any, ...]) -> str:
    text = ""
    for part in loc:
        if part in TAGS:
            continue
        text += f"[{part}]" if isinstance(part, int) else f".{part}" if text else str(part)
    return text


def _at(data: Any, loc: tuple[Any, ...]) -> Any:
    for part in loc:
        if part in TAGS:
            continue
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return None
    return data


def _unwrap(hint: Any, tag: Any = None) -> Any:
    """The dataclass or type inside ``Annotated``, ``X | None`` or a tagged union (``tag`` picks)."""
    while True:
        origin = typing.get_origin(hint)
        if origin is typing.Annotated:
            hint = typing.get_args(hint)[0]
        elif origin is typing.Union or isinstance(hint, types.UnionType):
            options = [a for a in typing.get_args(hint) if a is not type(None)]
            hint = options[TAGS.index(tag)] if tag in TAGS and len(options) == len(TAGS) else options[0]
        else:
            return hint


def _hint(cls: Any, loc: tuple[Any, ...]) -> Any:
    """The type declared at ``loc`` below ``cls`` (None where the walk leaves the declared types)."""
    hint = cls
    parts = list(loc)
    while parts:
        part = parts.pop(0)
        if part in TAGS:
            hint = _unwrap(hint, part)
            continue
        hint = _unwrap(hint, parts[0] if parts else None)
        if isinstance(part, int):
            arguments = typing.get_args(hint)
            if typing.get_origin(hint) is not tuple or not arguments:
                return None
            hint = arguments[0] if arguments[-1] is Ellipsis else arguments[min(part, len(arguments) - 1)]
        elif dataclasses.is_dataclass(hint):
            hint = typing.get_type_hints(hint, include_extras=True).get(part)
        else:
            return None
    return _unwrap(hint)


def _fields(cls: Any, loc: tuple[Any, ...]) -> list[str]:
    """The keys allowed at ``loc``."""
    hint = _hint(cls, loc)
    return sorted(f.name for f in dataclasses.fields(hint)) if dataclasses.is_dataclass(hint) else []


def _length(cls: Any, loc: tuple[Any, ...]) -> str:
    """How many values the tuple at ``loc`` holds, as declared."""
    arguments = typing.get_args(_hint(cls, loc))
    return str(len(arguments)) if arguments and arguments[-1] is not Ellipsis else "the declared number of"


def _message(error: Any, cls: Any, data: Any, ambiguous: dict[tuple[Any, ...], Ambiguous]) -> tuple[str, str]:
    """The key (relative to ``data``) and the problem of pydantic's ``error``."""
    loc, kind = tuple(error["loc"]), error["type"]
    key = _key(loc)
    got = show(_at(data, loc))
    if kind in ("unexpected_keyword_argument", "extra_forbidden"):
        return key, f"unknown key; allowed keys here: {_fields(cls, loc[:-1])}"
    if kind == "missing":
        if isinstance(loc[-1], int):  # a fixed-length tuple given fewer values
            return _key(loc[:-1]), f"needs {_length(cls, loc[:-1])} values, got {len(_at(data, loc[:-1]) or ())}"
        return key, "missing required key"
    if kind == "value_error":
        cause = (error.get("ctx") or {}).get("error")
        if isinstance(cause, ParameterError):
            return _join(key, cause.name), cause.problem
        if isinstance(cause, ConfigError) and ": " in str(cause):
            inner, _, problem = str(cause).partition(": ")
            return _join(key, inner), problem
        return key, str(cause)
    plain = tuple(p for p in loc if p not in TAGS)
    if plain in ambiguous and kind in ("float_type", "int_type", "bool_type"):
        text = ambiguous[plain]
        return key, (
            f"{str(text)!r} is ambiguous: YAML 1.1 reads it as {text.reading}; "
            "write the number without a leading zero, colon or underscore (e.g. 10, 90, 0.002)"
        )
    if kind == "literal_error":
        choices = list(typing.get_args(_hint(cls, loc))) or (error.get("ctx") or {}).get("expected", "")
        return key, f"must be one of {choices}, got {got}"
    if kind in ("too_long", "too_short"):
        return key, f"needs {_length(cls, loc)} values, got {len(_at(data, loc) or ())}"
    problems = {
        "bool_type": "must be true or false",
        "int_type": "must be an integer",
        "float_type": "must be a number",
        "finite_number": "must be a finite number",
        "string_type": "must be a string",
        "tuple_type": "must be a list",
        "list_type": "must be a list",
        "dataclass_type": "must be a mapping",
        "dict_type": "must be a mapping",
        "union_tag_not_found": "needs exactly one of the keys ['start', 'waypoints']",
        "union_tag_invalid": "needs exactly one of the keys ['start', 'waypoints']",
    }
    return key, f"{problems.get(kind, error['msg'])}, got {got}"
