"""What a robot driven by hand reads and writes: a trial's commands as columns, and the pose it
stopped at, as a person or a script hands it over: typed, in a file it wrote, or in a ROS bag.

:func:`commands_csv` is a trial's ``commands.csv`` in a session folder: its request's samples as
columns (``t, v1, v2, u1, u2`` and the nominal path), for a robot that plays them.
``session record --final X Y THETA [PHI]`` takes a pose typed (:func:`typed_pose`); ``--pose-file
PATH`` takes the last pose of a measured trajectory (odometry, motion capture), world frame
(:func:`final_pose`):

- a CSV with a header naming the robot's coordinates (a car: ``x``, ``y``, ``theta`` or ``yaw``
  [m, rad], and optionally ``phi``; a car with a trailer: ``x1``, ``y1``, ``theta1``, ``phi``,
  ``delta``; the Greek letters do too); other columns (a time) are ignored; the last row is the end.
  Only its header and its last row are read, so its size costs nothing; a byte order mark is no
  part of the first name;
- a ROS 2 bag (its folder, or an ``.mcap`` / ``.db3`` file in it) or a ROS 1 ``.bag``, read with
  `rosbags <https://gitlab.com/ternaris/rosbags>`_ (pure Python, ``pip install
  "ilc-steering[rosbags]"``): the last message of the topic ``topic`` (or of the only topic of type
  ``nav_msgs/msg/Odometry``, ``geometry_msgs/msg/PoseStamped`` or
  ``geometry_msgs/msg/PoseWithCovarianceStamped``), its position's ``x, y`` and its orientation's
  yaw (a quaternion of no length is no orientation, and refused).

A pose that cannot be this robot's is refused in one line naming where it came from (``ValueError``).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ilc_steering.core.plants import PlantKind
from ilc_steering.core.robots.car import CAR
from ilc_steering.core.robots.process_limits import steering_index
from ilc_steering.errors import BadInput
from ilc_steering.readers import open_regular

__all__ = ["MAX_ROW_BYTES", "POSE_TYPES", "commands_csv", "final_pose", "typed_pose"]

MAX_ROW_BYTES = 1 << 20
"""The longest header or last row of a CSV of poses read [bytes]."""
POSE_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped")
"""The message types whose last pose a bag's topic gives."""
_BAGS = (".bag", ".mcap", ".db3")
_LATIN = {"θ": "theta", "φ": "phi", "δ": "delta"}


def commands_csv(request: dict[str, Any]) -> str:
    """The request's samples as columns: time, the chained inputs, the robot's nominal inputs, the nominal pose."""
    control, nominal = request["control"], request["nominal"]
    q = np.asarray(nominal["q"], dtype=np.float64)
    coordinates = ["x", "y", "theta", "phi"][: q.shape[1]]
    lines = [",".join(["t", "v1", "v2", "u1", "u2", *(f"nominal_{c}" for c in coordinates)])]
    for i, t in enumerate(control["t"]):
        row = [t, control["v1"][i], control["v2"][i], nominal["u1"][i], nominal["u2"][i], *q[i]]
        lines.append(",".join(repr(float(v)) for v in row))
    return "\n".join(lines) + "\n"


def _names(label: str, index: int) -> tuple[str, ...]:
    """The column names of the coordinate ``label`` (``θ [rad]``): itself, spelled out, ``yaw`` for the heading."""
    name = label.split()[0]
    spelled = _LATIN.get(name[:1], name[:1]) + name[1:]
    return tuple(dict.fromkeys((name.lower(), spelled, *(["yaw"] if index == 2 else []))))


def _optional(kind: PlantKind) -> int | None:
    """The index of a coordinate that may be left out (a steering angle last: the commanded one is taken)."""
    phi = steering_index(kind)
    return phi if phi == len(kind.coordinates) - 1 else None


def _listed(kind: PlantKind) -> str:
    return ", ".join(label.split()[0] for label in kind.coordinates)


def typed_pose(final: Sequence[float], kind: PlantKind, commanded: Sequence[float], where: str) -> list[float]:
    """``final`` as the pose of a robot of ``kind`` (world frame), from ``where`` (``--final``, a
    file): its coordinates' count of finite numbers, or one fewer when the last is a steering angle,
    then the ``commanded`` one (the end of the nominal path) is taken."""
    values, n = [float(v) for v in final], len(kind.coordinates)
    optional = _optional(kind)
    if optional is not None and len(values) == n - 1:  # no steering angle measured: the commanded one
        values.append(float(commanded[optional]))
    if len(values) != n or not all(math.isfinite(v) for v in values):
        left = f"; without {kind.coordinates[-1].split()[0]}, the commanded one" if optional is not None else ""
        raise BadInput(f"{where} needs {n} finite numbers ({_listed(kind)}; world frame{left}), got {list(final)}")
    return values


def final_pose(path: Path, topic: str | None = None, kind: PlantKind = CAR) -> list[float]:
    """The last pose of the file at ``path`` for a robot of ``kind``: each of its coordinates in order,
    a steering angle last only if the file holds one (see the module)."""
    path = Path(path)
    if path.is_dir() or path.suffix in _BAGS:
        if len(kind.coordinates) - (_optional(kind) is not None) != 3:
            raise BadInput(f"{path}: a bag's pose is x, y, a heading; this robot's is {_listed(kind)}: give a CSV")
        return _bag_pose(path, topic)
    if topic is not None:
        raise BadInput(f"{path}: --topic is for a ROS bag; a CSV's columns are the pose's ({_listed(kind)})")
    return _csv_pose(path, kind)


def _csv_pose(path: Path, kind: PlantKind) -> list[float]:
    header, last = _first_and_last_rows(path)
    if last is None:
        raise BadInput(f"{path}: needs a header ({_listed(kind)}) and at least one row of numbers")
    names = [name.strip().lower() for name in header]
    values = []
    for index, label in enumerate(kind.coordinates):
        found = next((name for name in _names(label, index) if name in names), None)
        if found is None and index == _optional(kind):
            break
        if found is None:
            wanted = _names(label, index)
            others = f" (nor {', '.join(map(repr, wanted[:-1]))})" if len(wanted) > 1 else ""
            raise BadInput(f"{path}: its header {header} has no column {wanted[-1]!r}{others}")
        column = names.index(found)
        cell = last[column].strip() if column < len(last) else ""
        try:
            value = float(cell)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise BadInput(f"{path}: the last row's {found} is {cell!r}, not a finite number")
        values.append(value)
    return values


def _first_and_last_rows(path: Path) -> tuple[list[str], list[str] | None]:
    """The CSV's header and its last row that is not blank (``None``: there is none), read from its
    two ends: at most :data:`MAX_ROW_BYTES` of each, whatever the file's size."""
    with os.fdopen(open_regular(path), "rb") as file:
        first = file.readline(MAX_ROW_BYTES + 1)
        size, start = os.fstat(file.fileno()).st_size, len(first)
        header = next(csv.reader([first.decode("utf-8-sig", errors="replace")]), [])
        if len(first) > MAX_ROW_BYTES or not any(cell.strip() for cell in header):
            raise BadInput(f"{path}: its first line is no header of at most {MAX_ROW_BYTES} bytes")
        cut = size - MAX_ROW_BYTES > start  # the tail read starts inside the file: a byte before it, to see
        file.seek(size - MAX_ROW_BYTES - 1 if cut else start)  # whether its first line is whole
        tail = file.read(MAX_ROW_BYTES + 1)
    end = len(tail)
    while end > 0:  # the lines from the last, each parsed alone: the tail is never split into all its lines
        begin = max(tail.rfind(b"\n", 0, end), tail.rfind(b"\r", 0, end)) + 1
        if cut and begin == 0:
            break  # a line cut by the read
        row = next(csv.reader([tail[begin:end].decode("utf-8", errors="replace")]), [])
        if any(cell.strip() for cell in row):
            return header, row
        end = begin - 1
    if size - start > MAX_ROW_BYTES:
        raise BadInput(f"{path}: its last {MAX_ROW_BYTES} bytes hold no row of numbers")
    return header, None


def _bag_pose(path: Path, topic: str | None) -> list[float]:
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise BadInput(f'{path}: a ROS bag needs rosbags: pip install "ilc-steering[rosbags]"') from None
    bag = path.parent if path.is_file() and path.suffix in (".mcap", ".db3") else path
    try:
        with AnyReader([bag]) as reader:
            topics = sorted({(c.topic, c.msgtype) for c in reader.connections})
            poses = [c for c in reader.connections if c.msgtype in POSE_TYPES]
            if topic is not None:
                chosen = [c for c in reader.connections if c.topic == topic]
                if not chosen:
                    raise BadInput(f"{path}: no topic {topic!r}; it has {sorted({t for t, _ in topics})}")
                if chosen[0].msgtype not in POSE_TYPES:
                    raise BadInput(f"{path}: topic {topic!r} is a {chosen[0].msgtype}, not one of {list(POSE_TYPES)}")
            elif not poses:
                raise BadInput(f"{path}: no topic of a pose type {list(POSE_TYPES)}; its topics: {topics}")
            elif len({c.topic for c in poses}) != 1:
                found = sorted({c.topic for c in poses})
                raise BadInput(f"{path}: {len(found)} pose topics {found}; say which with --topic")
            else:
                chosen = poses
            last: Any = None
            for connection, _, data in reader.messages(connections=chosen):
                last = reader.deserialize(data, connection.msgtype)
    except ValueError:
        raise
    except Exception as error:  # rosbags' own errors: a folder that is not a bag, a torn file
        raise BadInput(f"{path}: cannot read it as a ROS bag ({type(error).__name__}: {error})") from None
    if last is None:
        raise BadInput(f"{path}: the topic {chosen[0].topic!r} holds no message")
    pose = last.pose.pose if hasattr(last.pose, "pose") else last.pose  # Odometry / WithCovariance: nested
    q = pose.orientation
    norm = math.sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w)
    if not (math.isfinite(norm) and norm > 1e-6):
        raise BadInput(f"{path}: the last pose's orientation is no rotation (a quaternion of length {norm:g})")
    x, y, z, w = (q.x / norm, q.y / norm, q.z / norm, q.w / norm)
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    values = [float(pose.position.x), float(pose.position.y), yaw]
    if not all(math.isfinite(v) for v in values):
        raise BadInput(f"{path}: the last pose {values} is not finite")
    return values
