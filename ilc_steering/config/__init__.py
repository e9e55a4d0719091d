"""Scenario configs: frozen dataclasses loaded from YAML.

Three modules: :mod:`.sections` (task, learning, simulation), :mod:`.steering` (the whole scenario
and its cross-key checks) and :mod:`.loading` (files, packaged configs, the robot's keys).

Every key is checked: an unknown key, a wrong type, a missing field or an out-of-range value
raises :class:`ConfigError` naming the key and the file. Units are in the field comments and in
the packaged YAML files (``configs/``).

The YAML is read strictly where YAML 1.1 (PyYAML) and a reader disagree: a number with a leading
zero (``010``, octal 8 to YAML 1.1, 10 to YAML 1.2), a sexagesimal one (``1:30``, 90 to YAML
1.1) and one with an underscore (``0.0_2``, 0.002 to YAML 1.1, text to YAML 1.2) are refused for
a numeric key, naming the key and both readings; the same text under a string key stays text.
``1e-3`` is the number it looks like; merge keys (``<<: *defaults``) are
honoured. A file is read through :mod:`ilc_steering.readers`: its size checked before it is read
(:data:`MAX_FILE_BYTES`), its nesting after (:data:`~ilc_steering.readers.MAX_DEPTH`).
"""

from ilc_steering.config.loading import MAX_FILE_BYTES, config_data, load_config, packaged_configs, plant_config
from ilc_steering.config.sections import (
    MAX_ACTION_BOUND,
    MAX_TRIALS,
    CyclicTaskConfig,
    LearningConfig,
    LegConfig,
    SegmentConfig,
    SegmentedTaskConfig,
    SimulationConfig,
    TaskConfig,
    ToleranceConfig,
)
from ilc_steering.config.steering import MIN_TRAVEL, SteeringConfig

__all__ = [
    "MAX_ACTION_BOUND",
    "MAX_FILE_BYTES",
    "MAX_TRIALS",
    "MIN_TRAVEL",
    "CyclicTaskConfig",
    "LearningConfig",
    "LegConfig",
    "SegmentConfig",
    "SegmentedTaskConfig",
    "SimulationConfig",
    "SteeringConfig",
    "TaskConfig",
    "ToleranceConfig",
    "config_data",
    "load_config",
    "packaged_configs",
    "plant_config",
]
