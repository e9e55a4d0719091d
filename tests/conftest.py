"""Shared test settings: the property suite is derandomized in CI, so a run there never flakes.

With ``CI`` set (GitHub Actions and ``.ci/run`` set it), hypothesis draws its examples from a
fixed seed (``derandomize=True``) and keeps no example database; locally it explores at random.
"""

import os

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(scope="session")
def quick_comparison(tmp_path_factory):
    """The run folder of ``ilc-steering compare --quick`` (every default method, both priors, six tasks, seeds
    0 and 1), computed once per session: the slow tier's tests that read a whole quick comparison share it."""
    from ilc_steering.cli import main

    out = tmp_path_factory.mktemp("quick_comparison") / "run"
    assert main(["compare", "--quick", "--out", str(out)]) == 0
    return out
