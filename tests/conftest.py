"""Shared test settings: the property suite is derandomized in CI, so a run there never flakes.

With ``CI`` set (GitHub Actions and ``.ci/run`` set it), hypothesis draws its examples from a
fixed seed (``derandomize=True``) and keeps no example database; locally it explores at random.
"""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
