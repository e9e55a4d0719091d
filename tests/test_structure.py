"""The package's seams: light imports, no import cycles, a pure core, an agent that cannot reach the plant."""

import ast
import functools
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# Source folder -> the package it installs as (pyproject.toml's package-dir).
FOLDERS = {
    "ilc_steering": "ilc_steering",
    "ilc_steering/core": "ilc_steering.core",
    "ilc_steering/core/robots": "ilc_steering.core.robots",
    "ilc_steering/config": "ilc_steering.config",
    "ilc_steering/engine": "ilc_steering.engine",
    "ilc_steering/compare": "ilc_steering.compare",
    "ilc_steering/sweep": "ilc_steering.sweep",
    "envs": "ilc_steering.envs",
    "agents": "ilc_steering.agents",
}
HEAVY = ("numba", "yaml", "matplotlib", "scipy.optimize", "torch", "stable_baselines3")


def modules():
    """Every module of the package: name -> source path."""
    found = {}
    for folder, package in FOLDERS.items():
        for path in sorted((ROOT / folder).glob("*.py")):
            found[package if path.stem == "__init__" else f"{package}.{path.stem}"] = path
    return found


MODULES = modules()


def imports(path):
    """Every module an import statement in ``path`` names, function-level imports included."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


@functools.cache
def _imports_of(name):
    return frozenset(imports(MODULES[name]))


def edges(name, parents=False):
    """The package's modules that ``name`` imports; with ``parents``, also the parent packages that
    importing it runs first."""
    targets = {m for m in _imports_of(name) if m in MODULES}
    if parents:
        parts = name.split(".")
        targets.update(".".join(parts[:i]) for i in range(1, len(parts)) if ".".join(parts[:i]) in MODULES)
    return targets - {name}


def closure(name, parents=False):
    """Every module of the package that importing ``name`` reaches."""
    seen, todo = set(), [name]
    while todo:
        for target in edges(todo.pop(), parents):
            if target not in seen:
                seen.add(target)
                todo.append(target)
    return seen


def loaded_after(statement):
    """The modules in ``sys.modules`` after ``statement`` in a fresh interpreter."""
    code = f"import json, sys\n{statement}\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd="/")
    return set(json.loads(out.stdout))


def test_the_walk_sees_every_module():
    assert {"ilc_steering.core.nominal", "ilc_steering.envs.scenario", "ilc_steering.agents.ilc"} <= set(MODULES)
    assert "ilc_steering.core.chained_form" in edges("ilc_steering.core.nominal")


def find_cycle(graph):
    """A cycle of ``graph`` (node -> its successors) as a path that ends where it starts, or None:
    a depth-first walk that visits each node once (the walk of every path took minutes)."""
    done, path = set(), []

    def visit(node):
        if node in path:
            return [*path[path.index(node) :], node]
        if node in done:
            return None
        path.append(node)
        for target in sorted(graph(node)):
            cycle = visit(target)
            if cycle:
                return cycle
        path.pop()
        done.add(node)
        return None

    for node in sorted(MODULES) if graph is edges else sorted(graph.nodes):
        cycle = visit(node)
        if cycle:
            return cycle
    return None


class _Graph(dict):
    @property
    def nodes(self):
        return set(self)

    def __call__(self, node):
        return self.get(node, set())


def test_the_cycle_finder_finds_a_cycle_and_only_a_cycle():
    assert find_cycle(_Graph(a={"b"}, b={"c"}, c={"a"}, d={"a"})) == ["a", "b", "c", "a"]
    assert find_cycle(_Graph(a={"b", "c"}, b={"c"}, c=set(), d={"a", "c"})) is None


def test_no_import_cycles():
    cycle = find_cycle(edges)
    assert cycle is None, " -> ".join(cycle)


@pytest.mark.parametrize("name", sorted(m for m in MODULES if m.startswith("ilc_steering.core")))
def test_the_core_imports_no_gymnasium_yaml_env_or_agent(name):
    # The parent package is left out: its __init__ only registers the env ids (see the next tests).
    reached = closure(name) | {name}
    assert not [m for m in reached if m.startswith(("ilc_steering.envs", "ilc_steering.agents"))]
    assert "ilc_steering.config" not in reached
    third_party = {m.split(".")[0] for r in reached for m in imports(MODULES[r])}
    assert not third_party & {"gymnasium", "yaml", "matplotlib", "torch", "stable_baselines3"}


def test_the_package_inits_import_no_module_of_the_package():
    for name in ("ilc_steering", "ilc_steering.core", "ilc_steering.envs"):
        assert edges(name) == set(), name
    assert {m.split(".")[0] for m in imports(MODULES["ilc_steering"])} <= {
        "__future__",
        "importlib",
        "typing",
        "gymnasium",
    }


@pytest.mark.parametrize(
    "agent", ["ilc_steering.agents.ilc", "ilc_steering.agents.cyclic_ilc", "ilc_steering.agents.base"]
)
def test_the_nominal_model_and_the_agents_have_no_route_to_the_true_plant(agent):
    plant_side = {
        "ilc_steering.core.plants",
        "ilc_steering.core.simulate",
        "ilc_steering.core.integrate",
        "ilc_steering.core.reference",
        "ilc_steering.config",
    }
    for name in ("ilc_steering.core.nominal", agent):
        reached = closure(name, parents=True)
        assert not reached & plant_side, (name, reached & plant_side)
        assert not [m for m in reached if m.startswith("ilc_steering.envs")]


def test_import_ilc_steering_registers_the_envs_and_loads_nothing_heavy():
    loaded = loaded_after(
        "import ilc_steering, gymnasium\nassert 'ilc_steering/ChainedSteering-v0' in gymnasium.registry"
    )
    assert not [m for m in loaded if m.split(".")[0] in HEAVY or m in HEAVY]
    assert not [m for m in loaded if m.startswith(("ilc_steering.envs.", "ilc_steering.agents."))]


def test_the_agent_loads_neither_numba_nor_yaml():
    loaded = loaded_after("from ilc_steering.agents import ILCAgent")
    assert "numba" not in loaded and "yaml" not in loaded
    assert not [m for m in loaded if m.startswith("ilc_steering.envs")]


def test_lazy_names_resolve():
    import ilc_steering
    from ilc_steering import envs

    assert ilc_steering.load_config("forward_parking").name == "forward_parking"
    assert envs.ChainedSteeringEnv.__name__ == "ChainedSteeringEnv"
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = ilc_steering.nope


@pytest.mark.parametrize(
    "learner", ["ilc_steering.agents.newton_ilc", "ilc_steering.agents.robust_ilc", "ilc_steering.agents.costs"]
)
def test_the_learners_that_simulate_use_their_own_family_never_the_env_plant(learner):
    # newton_ilc and the cost of section 7 simulate plants, but only those a ModelFamily builds from
    # the nominal model: they reach the plant classes and the kernel, never an env, the config or
    # the reference.
    reached = closure(learner, parents=True)
    assert "ilc_steering.core.family" in reached
    assert not [m for m in reached if m.startswith("ilc_steering.envs")]
    assert not reached & {"ilc_steering.config", "ilc_steering.core.reference"}
    import inspect

    from ilc_steering.core.family import ModelFamily

    # the nominal model, the step and the names of the actuator parameters it frees: nothing of the true plant
    assert list(inspect.signature(ModelFamily).parameters) == ["model", "max_step", "actuators"]


DISPATCH = re.compile(
    r"isinstance\([^)]*(CarModel|UnicycleModel|TrailerModel|CarPlant|ChainedPlant|UnicyclePlant|TrailerPlant)\b"
    r"|_FIELD\b|chained_map is (not )?None"
    r"|getattr\([^)]*\"(steering_limit|lab|servo|steering_lag|speed_lag)\""
    r"|\.model == \"(car|chained|unicycle|car_trailer)\""
)


def test_no_robot_kind_dispatch_outside_the_robots_modules():
    """A robot is one module and one registry line: nothing else asks what kind of robot it is
    (``isinstance`` of a robot's class, field ids, ``is None`` tests of a map, ``getattr`` of a
    robot's attributes, comparisons of ``plant.model``)."""
    found = []
    for name, path in MODULES.items():
        if name.startswith("ilc_steering.core.robots"):
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if DISPATCH.search(line) and "None stands for ChainedForm" not in line:
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    for path in sorted((ROOT / "benchmarks").glob("*.py")):
        found += [f"{path.name}: {line.strip()}" for line in path.read_text().splitlines() if DISPATCH.search(line)]
    assert not found, "\n".join(found)


# The floors, bottom first (docs/layout.md): a module may name (import, or write as a string that
# is a module's or an entry's name) only modules of its own floor or below. The package's
# __init__ is the roof: it registers the env ids by their entry strings and imports nothing.
FLOORS = (
    ("base", ("ilc_steering.errors", "ilc_steering.entries", "ilc_steering.arguments")),
    ("core", ("ilc_steering.core",)),
    ("spaces", ("ilc_steering.boxes",)),
    (
        "files",
        (
            *("ilc_steering.readers", "ilc_steering.yaml_reader", "ilc_steering.schema", "ilc_steering.output"),
            "ilc_steering.pose_files",
            *("ilc_steering.tables", "ilc_steering.figure_styles"),
        ),
    ),
    ("config", ("ilc_steering.config",)),
    ("envs", ("ilc_steering.envs", "ilc_steering.lab_robot")),
    ("agents", ("ilc_steering.agents",)),
    (
        "trials",
        (
            "ilc_steering.loop",
            "ilc_steering.trial_board",
            "ilc_steering.segmented",
            "ilc_steering.verdict",
            "ilc_steering.preflight",
            "ilc_steering.runner",
            "ilc_steering.oracle",
            "ilc_steering.plots",
            "ilc_steering.console",
        ),
    ),
    ("engine", ("ilc_steering.engine",)),
    (
        "commands",
        (
            "ilc_steering.compare",
            "ilc_steering.sweep",
            "ilc_steering.reproduce",
            "ilc_steering.session_folder",
            "ilc_steering.session",
            "ilc_steering.session_cli",
            "ilc_steering.current",
            "ilc_steering.cli",
        ),
    ),
)
ROOF = {"ilc_steering", "ilc_steering.__main__"}
MODULE_NAME = re.compile(r"\bilc_steering(?:\.\w+)+")


def floor(name):
    """The floor of module ``name`` (its index in FLOORS), by the longest prefix that names it."""
    best = None
    for index, (_, prefixes) in enumerate(FLOORS):
        for prefix in prefixes:
            if name == prefix or name.startswith(prefix + "."):
                if best is None or len(prefix) > best[0]:
                    best = (len(prefix), index)
    return None if best is None else best[1]


def named_modules(path):
    """Every module of the package that ``path`` imports or names in a string (an entry
    ``module:attr``, an ``import_module`` argument, a table of entries); docstrings are prose and
    left out."""
    tree = ast.parse(path.read_text())
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    names = {m for m in imports(path) if m in MODULES}
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            for found in MODULE_NAME.findall(node.value):
                while found not in MODULES and "." in found:
                    found = found.rsplit(".", 1)[0]
                names.add(found)
    return names - {path.name}


def test_every_module_has_a_floor():
    assert not [name for name in MODULES if name not in ROOF and floor(name) is None]
    assert floor("ilc_steering.compare.plan") == floor("ilc_steering.cli") > floor("ilc_steering.engine.runs")
    assert floor("ilc_steering.core.robots.car") == 1 and floor("ilc_steering.errors") == 0
    assert floor("ilc_steering.boxes") < floor("ilc_steering.envs") < floor("ilc_steering.agents")


@pytest.mark.parametrize("name", sorted(set(MODULES) - ROOF))
def test_no_stair_goes_up(name):
    """A lower floor never names a higher one, not even in a string; the core's robots table
    names only the core's robots (plants above it register as entry points, pyproject.toml)."""
    up = sorted(
        target
        for target in named_modules(MODULES[name])
        if target not in ROOF and target in MODULES and floor(target) > floor(name)
    )
    assert not up, f"{name} (floor {FLOORS[floor(name)][0]}) names a higher floor: {up}"


def test_the_stair_check_sees_a_string_and_a_function_level_import(tmp_path):
    path = tmp_path / "bad.py"
    path.write_text(
        '"""Mentions ilc_steering.cli in prose only."""\n'
        'ROBOTS = {"x": "ilc_steering.envs.highway:HighwayPlantConfig"}\n'
        "def f():\n    from ilc_steering.compare.command import main\n"
    )
    assert named_modules(path) >= {"ilc_steering.envs.highway", "ilc_steering.compare.command"}
    assert "ilc_steering.cli" not in named_modules(path)


def test_no_module_of_the_package_is_imported_by_a_string_outside_the_one_loader():
    """A dynamic import of the package's own code hides an edge from every static tool: the package
    imports itself statically, and ``module:attr`` entries go through ``entries.load_entry`` (or a
    package ``__init__``'s lazy table)."""
    found = []
    for name, path in MODULES.items():
        if name == "ilc_steering.entries" or path.name == "__init__.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", "")) in (
                "import_module",
                "__import__",
            ):
                argument = node.args[0] if node.args else None
                text = ast.unparse(argument) if argument is not None else ""
                if text.strip("f'\"").startswith("ilc_steering"):
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}: {text}")
    assert not found, found


MAX_LINES = 400


def test_no_room_over_400_lines():
    """No module of the package (``envs/`` and ``agents/`` included) over :data:`MAX_LINES` lines."""
    sizes = {
        str(path.relative_to(ROOT)): len(path.read_text().splitlines())
        for folder in FOLDERS
        for path in (ROOT / folder).glob("*.py")
    }
    assert len(sizes) > 100
    over = {name: lines for name, lines in sizes.items() if lines > MAX_LINES}
    assert not over, f"over {MAX_LINES} lines: {over}"


def test_the_layout_page_states_the_floors_this_test_enforces():
    """docs/layout.md's table of floors names, floor by floor, exactly the modules of FLOORS."""
    text = (ROOT / "docs" / "layout.md").read_text()
    start = text.index("| floor | modules | what it holds |")
    rows = [line for line in text[start:].splitlines()[2:] if line.startswith("|")]
    stated = {}
    for row in rows[: len(FLOORS)]:
        name, modules = (cell.strip() for cell in row.strip("|").split("|")[:2])
        names = re.findall(r"`([a-z_/]+)`", re.sub(r"\([^)]*\)", "", modules))
        stated[name] = sorted("ilc_steering." + n.rstrip("/").removesuffix(".py").replace("/", ".") for n in names)
    enforced = {name: sorted(prefixes) for name, prefixes in FLOORS}
    assert stated == enforced
