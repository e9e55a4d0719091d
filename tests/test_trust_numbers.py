"""Numbers on the command line as a program prints them (issue 64).

A script that records a pose prints it with ``repr``, ``%g`` or ``%e``; a small negative is then
``-1e-05``, which argparse's own pattern (``-1``, ``-0.5``) took for an option: "unrecognized
arguments". Every float a program prints is read back as itself, wherever an option takes numbers.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_steering.cli import _parser

FORMATS = [repr, str, "{:g}".format, "{:e}".format, "{:.3e}".format, "{:.17g}".format, "{:E}".format]


def _read(argv: list[str]) -> list[float]:
    return list(_parser().parse_args(["session", "record", "s", "--final", *argv]).final)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=3, max_size=4),
    st.sampled_from(FORMATS),
)
def test_a_pose_printed_by_a_program_is_read_as_printed(pose: list[float], show) -> None:
    printed = [show(v) for v in pose]
    assert _read(printed) == [float(text) for text in printed]


@pytest.mark.parametrize(
    "text", ["-1e-05", "-1E-05", "-1.5e+300", "-.5", "-5.", "-0", "-0.0", "-1_000.5", "-inf", "-Infinity", "-nan"]
)
def test_each_notation_of_a_negative_number_is_a_value(text: str) -> None:
    (value,) = _read(["1.8", "0.8", text])[2:]
    assert value == float(text) or (math.isnan(value) and math.isnan(float(text)))


def test_an_option_is_still_an_option_and_a_typo_still_refused(capsys: pytest.CaptureFixture[str]) -> None:
    args = _parser().parse_args(["session", "record", "s", "--final", "1", "-2e-3", "0", "--topic", "/odom"])
    assert args.final == [1.0, -0.002, 0.0] and args.topic == "/odom"
    with pytest.raises(SystemExit) as stopped:
        _parser().parse_args(["session", "record", "s", "--final", "1", "0", "-1e-5x"])
    assert stopped.value.code == 2
    assert len(capsys.readouterr().err.splitlines()) == 1


def test_a_sweep_axis_takes_negative_bounds_in_any_notation() -> None:
    args = _parser().parse_args(["sweep", "forward_parking", "--axis", "steering_offset", "-3e-2", "3e-2"])
    assert args.axis == [["steering_offset", "-3e-2", "3e-2"]]
    args = _parser().parse_args(["sweep", "forward_parking", "--range", "1e-1", "2"])
    assert args.range == [0.1, 2.0]
