"""The clone imports as it installs, from its own root: ``envs/``, ``agents/`` and ``configs/`` are
symlinked into ``ilc_steering/``, so the local package (first on the path from the root) is whole."""

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def run_from_root(*args):
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=ROOT, timeout=600)


@pytest.mark.parametrize("link", ["envs", "agents", "configs"])
def test_the_top_level_folders_are_linked_into_the_package(link):
    path = ROOT / "ilc_steering" / link
    assert path.is_symlink() and path.resolve() == (ROOT / link).resolve()


def test_the_clones_own_modules_import_from_its_root():
    code = (
        "import ilc_steering, ilc_steering.agents, ilc_steering.envs.steering_env, ilc_steering.config as c\n"
        "print(ilc_steering.__file__); print(ilc_steering.agents.__file__)\n"
        "print(c.load_config('forward_parking').name)"
    )
    result = run_from_root("-c", code)
    assert result.returncode == 0, result.stderr[-2000:]
    package, agents, name = result.stdout.split()
    assert Path(package) == ROOT / "ilc_steering" / "__init__.py"
    assert Path(agents).resolve() == ROOT / "agents" / "__init__.py" and name == "forward_parking"


def test_the_readmes_python_example_runs_from_the_clones_root():
    code = re.search(r"^```python\n(.*?)^```$", (ROOT / "README.md").read_text(), re.M | re.S)[1]
    result = run_from_root("-c", code)
    assert result.returncode == 0, result.stderr[-2000:]
    assert len(result.stdout.splitlines()) == 6  # a line per trial


@pytest.mark.skipif(importlib.util.find_spec("highway_env") is None, reason="needs the [highway] extra")
@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_a_module_of_the_envs_runs_with_dash_m_from_the_clones_root():
    result = run_from_root("-m", "ilc_steering.envs.highway", "--seed", "13")
    assert result.returncode == 0, result.stderr[-2000:]
    assert "model: highway_parking" in result.stdout
