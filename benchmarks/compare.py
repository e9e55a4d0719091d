"""Trials to tolerance of ILC, RL (PPO, SAC, TD3), black-box and users' learners, across seeds and priors.

The benchmark lives in the package (:mod:`ilc_steering.compare.command`) so that the installed command
``ilc-steering compare`` runs it too; this script is the same entry point:

    python benchmarks/compare.py [--quick] [--out DIR] [--methods ...] [--scenarios ...] [--seeds ...]

``Args`` holds every knob, ``main(args)`` runs (or resumes) the run folder and writes
``compare.{csv,json,md}`` and ``compare_<scenario>.png`` there.
"""

from __future__ import annotations

from ilc_steering.compare.args import Args
from ilc_steering.compare.command import main, parse

__all__ = ["Args", "main"]

if __name__ == "__main__":
    main(parse())
