"""The code a result depends on: the import closure of the modules its computation starts from.

A cell of a comparison, a row of a map or a benchmark's artifact names its *roots*: the modules
its computation runs through that no import statement reaches (the env its ``gym.make`` id
names, the learner and the robot the registries name by ``module:attr`` strings), and the data
files it reads. :func:`closure` follows every ``import`` of the library's modules from them
(statically: the source's ``import`` statements, wherever they stand, ``TYPE_CHECKING`` blocks
left out; a package's lazy ``_LAZY`` table resolved for the names imported from it; a script's
imports of the files beside it), and hashes each file it reaches. A result records the hash of
its closure (:func:`code_of`); a change to a file outside it leaves the result current.

A root is

- a module's dotted name (``ilc_steering.agents.newton_ilc``), or a ``module:attr`` entry, whose
  module is taken;
- a data file of a package, ``package/relative/path`` (``ilc_steering.configs/rl/ppo.yaml``);
- a script's path relative to the checkout (``benchmarks/noisy.py``), or an absolute path.

The modules that keep and judge the records (:data:`BOOKKEEPING`) are never followed: they
decide what a record says about a result, not what the result holds, so a change to them stales
nothing.

Files are keyed by a path that is the same in a checkout and an installed wheel
(``ilc_steering/agents/newton_ilc.py``); a user's module outside the package by its file name.
``tests/test_closure.py`` checks the closure against what a fresh process running a cell imports.
"""

from __future__ import annotations

import ast
import hashlib
from collections.abc import Iterable, Mapping
from functools import cache, lru_cache
from importlib import util
from pathlib import Path

from ilc_steering.errors import BadInput

__all__ = ["BOOKKEEPING", "PACKAGE", "checkout", "closure", "code_of", "root_of_entry"]

PACKAGE = "ilc_steering"
"""The package whose imports a closure follows (and a script's files beside it)."""
BOOKKEEPING = frozenset(
    {"ilc_steering.engine.closure", "ilc_steering.engine.provenance", "ilc_steering.engine.staleness"}
)
"""The modules that record a result's provenance and judge it current: in no closure, unless a root
(the `current` command, which reads them, is imported by no computation)."""


def code_of(files: Mapping[str, str]) -> str:
    """16 hex digits of one hash of every file's key and digest."""
    text = "\n".join(f"{key} {digest}" for key, digest in sorted(files.items()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def root_of_entry(entry: str) -> str:
    """The module of a ``module:attr`` entry (a root)."""
    return entry.partition(":")[0]


@lru_cache(maxsize=1)
def checkout() -> Path:
    """A checkout's root, the folder a script's paths (``benchmarks/noisy.py``) are relative to: the
    folder that holds the package's folder when that is a checkout (an editable install), else the
    nearest checkout at or above the working directory (a wheel's package lives in site-packages,
    its scripts in the checkout it was built from), else the working directory."""
    beside = _package_folder(PACKAGE).parent
    if _is_checkout(beside):
        return beside
    here = Path.cwd().resolve()
    return next((folder for folder in (here, *here.parents) if _is_checkout(folder)), here)


def _is_checkout(folder: Path) -> bool:
    return (folder / "pyproject.toml").is_file() and (folder / PACKAGE).is_dir()


@cache
def _package_folder(package: str) -> Path:
    spec = util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        raise BadInput(f"{package}: not an installed package")
    return Path(next(iter(spec.submodule_search_locations)))


def _ours(name: str) -> bool:
    return name == PACKAGE or name.startswith(PACKAGE + ".")


@cache
def _module_file(name: str) -> Path | None:
    """The source file of module ``name`` of the package, or None if there is none."""
    parts = name.split(".")
    folder = _package_folder(PACKAGE).joinpath(*parts[1:])
    for candidate in (folder / "__init__.py", folder.with_suffix(".py")):
        if candidate.is_file():
            return candidate
    return None


def _key(name: str, path: Path) -> str:
    """``ilc_steering/agents/ilc.py`` for module ``ilc_steering.agents.ilc``: the same in a checkout and a wheel."""
    return "/".join(name.split(".")) + ("/__init__.py" if path.name == "__init__.py" else ".py")


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _import_nodes(tree: ast.AST) -> Iterable[ast.Import | ast.ImportFrom]:
    """Every import statement of ``tree``, at any depth, those under ``if TYPE_CHECKING:`` left out."""
    stack: list[ast.AST] = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
            continue
        children = list(ast.iter_child_nodes(node))
        if isinstance(node, ast.If) and _type_checking(node):
            children = list(node.orelse)
        stack.extend(children)


@cache
def _lazy_table(package: str) -> dict[str, str]:
    """A package's ``_LAZY`` table (name -> module), read from its ``__init__``'s source."""
    path = _module_file(package)
    if path is None or path.name != "__init__.py":
        return {}
    for node in ast.parse(path.read_text()).body:
        if not isinstance(node, ast.Assign) or not isinstance(node.value, ast.Dict):
            continue
        if any(isinstance(t, ast.Name) and t.id == "_LAZY" for t in node.targets):
            return {
                k.value: v.value
                for k, v in zip(node.value.keys, node.value.values)
                if isinstance(k, ast.Constant) and isinstance(k.value, str)
                and isinstance(v, ast.Constant) and isinstance(v.value, str)
            }  # fmt: skip
    return {}


def _imported(path: Path, package: str | None) -> tuple[set[str], set[Path]]:
    """The package's modules ``path`` imports (``package``: the package it belongs to, for relative
    imports; None for a script) and, for a script, the files beside it that it imports."""
    modules: set[str] = set()
    beside: set[Path] = set()
    for node in _import_nodes(ast.parse(path.read_text(), str(path))):
        names: list[tuple[str, str | None]]
        if isinstance(node, ast.Import):
            names = [(alias.name, None) for alias in node.names]
        else:
            base = node.module or ""
            if node.level and package is not None:
                parent = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{parent}.{base}" if base else parent
            names = [(base, alias.name) for alias in node.names]
        for module, name in names:
            if _ours(module):
                modules.add(module)
                if name is not None:
                    lazy = _lazy_table(module).get(name)
                    modules.add(lazy if lazy else f"{module}.{name}")
            elif package is None:
                sibling = path.parent / (module.split(".")[0] + ".py")
                if sibling.is_file():
                    beside.add(sibling)
    return {m for m in modules if _module_file(m) is not None}, beside


def _resolve(root: str) -> tuple[str, Path, str | None]:
    """A root's (key, file, module name or None)."""
    if "/" not in root and not root.endswith(".py"):
        module = root_of_entry(root)
        if _ours(module):
            path = _module_file(module)
            if path is None:
                raise BadInput(f"{root}: no module of {PACKAGE} of that name")
            return _key(module, path), path, module
        spec = util.find_spec(module)  # a user's module (its folder on sys.path)
        if spec is None or not spec.origin or not spec.origin.endswith(".py"):
            raise BadInput(f"{root}: no Python module of that name")
        return Path(spec.origin).name, Path(spec.origin), None
    head, _, rest = root.partition("/")
    if "." in head or head == PACKAGE:  # a package's data file
        folder = _package_folder(head)
        key = "/".join([*head.split("."), rest])
        return key, folder / rest, None
    path = Path(root) if Path(root).is_absolute() else checkout() / root
    return root, path, None


def closure(roots: Iterable[str]) -> dict[str, str]:
    """Every file the computation that starts at ``roots`` depends on -> the first 16 hex digits of
    its SHA-256, sorted by key; ``ValueError`` naming a root that is no module or file."""
    found: dict[str, str] = {}
    seen: set[str] = set()
    todo: list[tuple[str, Path, str | None]] = [_resolve(root) for root in roots]
    while todo:
        key, path, module = todo.pop()
        if key in seen:
            continue
        seen.add(key)
        if not path.is_file():
            raise BadInput(f"{key}: no such file ({path})")
        found[key] = _digest(path)
        if path.suffix != ".py":
            continue
        if module is not None:  # its parents' __init__ run first
            parts = module.split(".")
            for i in range(1, len(parts)):
                parent = ".".join(parts[:i])
                todo.append((_key(parent, _module_file(parent)), _module_file(parent), parent))  # type: ignore[arg-type]
            package = module if path.name == "__init__.py" else module.rpartition(".")[0]
            modules, beside = _imported(path, package)
        else:
            modules, beside = _imported(path, None)
        for name in modules - BOOKKEEPING:
            file = _module_file(name)
            assert file is not None
            todo.append((_key(name, file), file, name))
        for file in beside:
            key = file.relative_to(checkout()).as_posix() if file.is_relative_to(checkout()) else file.name
            todo.append((key, file, None))
    return dict(sorted(found.items()))
