"""Shared test settings: the property suite is derandomized in CI, so a run there never flakes;
a test that needs an optional extra says which (``@pytest.mark.extra("rl")``).

With ``CI`` set (GitHub Actions and ``.ci/run`` set it), hypothesis draws its examples from a
fixed seed (``derandomize=True``) and keeps no example database; locally it explores at random.

A test marked ``extra(name)`` is skipped, naming the extra to install, where that extra's packages
are missing (``pip install ".[test]"`` alone runs the rest); in CI, which installs every extra
(``.ci/run``), a missing one fails the test instead: nothing skips there unseen.
"""

import os
from importlib.util import find_spec

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

EXTRAS = {
    "rl": ("stable_baselines3", "sb3_contrib", "torch", "cma"),
    "rl-jax": ("sbx", "jax"),
    "bo": ("botorch",),
    "ray": ("ray",),
    "highway": ("highway_env",),
    "mujoco": ("mujoco",),
    "rosbags": ("rosbags",),
    "zoo": ("rl_zoo3",),
    "tensorboard": ("tensorboard",),
}
"""The modules each extra of pyproject.toml installs, as a test imports them."""


@pytest.hookimpl(tryfirst=True)  # before the test's fixtures are set up (the quick comparison's, for one)
def pytest_runtest_setup(item: pytest.Item) -> None:
    for mark in item.iter_markers("extra"):
        for extra in mark.args:
            missing = [module for module in EXTRAS[extra] if find_spec(module) is None]
            if missing:
                reason = f'needs the {extra} extra (pip install "ilc-steering[{extra}]"): {", ".join(missing)} missing'
                (pytest.fail if os.environ.get("CI") else pytest.skip)(reason)


@pytest.fixture(scope="session")
def quick_comparison(tmp_path_factory):
    """The run folder of ``ilc-steering compare --quick`` (every default method, both priors, six tasks, seeds
    0 and 1), computed once per session: the slow tier's tests that read a whole quick comparison share it."""
    from ilc_steering.cli import main

    out = tmp_path_factory.mktemp("quick_comparison") / "run"
    assert main(["compare", "--quick", "--out", str(out)]) == 0
    return out
