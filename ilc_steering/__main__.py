"""``python -m ilc_steering``: the ``ilc-steering`` command."""

import sys

from ilc_steering.cli import main

sys.exit(main())
