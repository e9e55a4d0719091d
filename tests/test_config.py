"""Config loading: the documented keys, and clear errors that name the key and the file."""

import pytest
import yaml

from ilc_steering.config import load_config, packaged_configs
from ilc_steering.errors import ConfigError

ISSUE_EXAMPLE = """
name: forward_parking
plant:
  model: car                 # car | chained
  wheelbase: 0.2             # nominal ℓ [m], known to the controller
  wheel_radius: 0.02         # nominal ρ [m]
  true_wheelbase: 0.22       # the simulated robot's ℓ [m]
  true_wheel_radius: 0.022   # the simulated robot's ρ [m]
  steering_limit: null       # bound on |φ| [rad]; null for none
task:
  start: [-1.0, 0.0, 0.7853981633974483, 0.0]   # x [m], y [m], θ [rad], φ [rad]
  goal:  [0.0, 0.0, 0.7853981633974483, 0.0]
  pieces: [5.0]              # Δ_i [s]; T is their sum
  v1_fixed: []               # c12..c1p: v1 on pieces 2..p
  v2_terms: 3                # q
learning:
  nu_a: 1.0
  nu_b: 1.0
  trials: 10
  tolerance: {cartesian: 5.0e-4, orientation: 5.0e-4}   # [m], [rad]
"""


def write(tmp_path, text, name="scenario.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def edited(**changes):
    data = yaml.safe_load(ISSUE_EXAMPLE)
    for dotted, value in changes.items():
        *parents, key = dotted.split("__")
        node = data
        for parent in parents:
            node = node[parent]
        if value is KeyError:
            del node[key]
        else:
            node[key] = value
    return yaml.safe_dump(data, allow_unicode=True)


def test_the_documented_example_loads_and_equals_the_packaged_config(tmp_path):
    assert load_config(write(tmp_path, ISSUE_EXAMPLE)) == load_config("forward_parking")


def test_every_packaged_config_loads():
    names = packaged_configs()
    assert {"forward_parking", "forward_parking_saturated", "parallel_parking", "chained_perturbed"} <= set(names)
    for name in names:
        assert load_config(name).name == name


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"plant__wheelbse": 0.2}, r"plant\.wheelbse: unknown key"),
        ({"extra": 1}, r"extra: unknown key"),
        ({"task__v2_terms": "three"}, r"task\.v2_terms: must be an integer"),
        ({"task__pieces": 5.0}, r"task\.pieces: must be a list"),
        ({"learning__nu_b": KeyError}, r"learning\.nu_b: missing required key"),
        ({"learning__nu_a": 2.5}, r"learning\.nu_a: must be in \(0, 2\)"),
        ({"plant__wheelbase": -0.2}, r"plant\.wheelbase: must be a length in \[0\.001, 1000\] m, got -0\.2"),
        (  # the packaged robots, then the installed packages' entry points (mujoco_car)
            {"plant__model": "truck"},
            r"plant\.model: must be one of \['car', 'chained', 'unicycle', 'car_trailer', 'process', "
            r"'highway_parking'",
        ),
        ({"plant__steering_limit": 2.0}, r"plant\.steering_limit"),
        ({"plant__steering_offset": 0.7}, r"plant\.steering_offset: must be within \+-0\.5 rad"),
        ({"plant__steering_offset": ".nan"}, r"plant\.steering_offset: must be a number"),
        ({"plant__encoder_pulses": 2.5}, r"plant\.encoder_pulses: must be an integer"),
        ({"plant__encoder_pulses": -1}, r"plant\.encoder_pulses: must be a whole number of pulses per turn"),
        ({"plant__encoder_pulses": True}, r"plant\.encoder_pulses: must be an integer"),
        ({"plant__steering_backlash": -0.01}, r"plant\.steering_backlash: must be in \[0, 0\.2\] rad"),
        ({"plant__steering_backlash": 0.5}, r"plant\.steering_backlash: must be in \[0, 0\.2\] rad"),
        ({"plant__steering_lag": -0.1}, r"plant\.steering_lag: must be in \[0, 10\] s"),
        ({"plant__speed_lag": 0.01}, r"plant\.speed_lag: 0\.01 s is shorter than the integrator step"),
        ({"plant__speed_lag": "fast"}, r"plant\.speed_lag: must be a number"),
        ({"task__v2_terms": 2}, r"task\.v2_terms: needs q >= n - 1 = 3"),
        ({"task__start": [0.0, 0.0, 0.0]}, r"task\.start: needs 4 values"),
        ({"task__start": [".nan", 0.0, 0.0, 0.0]}, r"task\.start\[0\]: must be a number"),
        ({"task__goal": [-1.0, 1.0, 0.5, 0.0]}, r"task\.v1_fixed: the start and goal share z1"),
        ({"task__v1_fixed": [0.1]}, r"task\.v1_fixed: needs one value per piece"),
        ({"learning__tolerance": {"error": 1e-3}}, r"learning\.tolerance: a car needs"),
        (
            {"task__frame": 100.0},
            r"task\.frame: 100\.0 rad puts task\.start at a heading of -99\.2",
        ),  # was blamed on task.start
    ],
)
def test_bad_configs_name_the_key_and_the_file(tmp_path, changes, message):
    path = write(tmp_path, edited(**changes), "broken.yaml")
    with pytest.raises(ConfigError, match=message) as error:
        load_config(path)
    assert "broken.yaml" in str(error.value)


def test_nan_in_yaml_is_rejected(tmp_path):
    text = ISSUE_EXAMPLE.replace("start: [-1.0,", "start: [.nan,")
    with pytest.raises(ConfigError, match=r"task\.start\[0\]: must be a finite number"):
        load_config(write(tmp_path, text))


def test_chained_plant_keys():
    config = load_config("chained_perturbed")
    assert (config.plant.dimension, config.plant.v1_gain, config.plant.v2_gain) == (5, 1.1, 0.9)
    assert config.learning.tolerance.error == 1e-6


def test_unknown_names_and_files():
    with pytest.raises(ConfigError, match="packaged: .*forward_parking"):
        load_config("no_such_scenario")
    with pytest.raises(ConfigError, match="no such config file"):
        load_config("missing/dir/scenario.yaml")
    assert issubclass(ConfigError, ValueError)


def test_an_integer_too_large_for_a_float_is_a_config_error(tmp_path):
    path = write(tmp_path, ISSUE_EXAMPLE.replace("start: [-1.0,", "start: [" + "9" * 400 + ","))
    with pytest.raises(ConfigError, match=r"task\.start\[0\]: must be a finite number"):
        load_config(path)
