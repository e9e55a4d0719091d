"""Where a robot stopped, read from a file it wrote: a CSV of poses, or a ROS bag of its odometry.

``session record --pose-file PATH`` takes the last pose of a measured trajectory (odometry, motion
capture) as the trial's final pose, world frame:

- a CSV with a header naming ``x``, ``y`` and ``theta`` (or ``yaw``) [m, rad], and optionally
  ``phi``; other columns (a time) are ignored; the last row is the end;
- a ROS 2 bag (its folder, or an ``.mcap`` / ``.db3`` file in it) or a ROS 1 ``.bag``, read with
  `rosbags <https://gitlab.com/ternaris/rosbags>`_ (pure Python, ``pip install
  "ilc-steering[rosbags]"``): the last message of the topic ``topic`` (or of the only topic of type
  ``nav_msgs/msg/Odometry``, ``geometry_msgs/msg/PoseStamped`` or
  ``geometry_msgs/msg/PoseWithCovarianceStamped``), its position's ``x, y`` and its orientation's
  yaw.

A file that cannot say a pose is refused in one line naming it (``ValueError``).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

from ilc_steering.errors import BadInput
from ilc_steering.readers import read_bytes

__all__ = ["MAX_POSE_FILE_BYTES", "POSE_TYPES", "final_pose"]

MAX_POSE_FILE_BYTES = 1 << 30
"""The largest CSV of poses read [bytes]."""
POSE_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped")
"""The message types whose last pose a bag's topic gives."""
_BAGS = (".bag", ".mcap", ".db3")


def final_pose(path: Path, topic: str | None = None) -> list[float]:
    """The last pose of the file at ``path``: ``[x, y, theta]`` or ``[x, y, theta, phi]`` (a CSV with
    ``phi``), world frame (see the module)."""
    path = Path(path)
    if path.is_dir() or path.suffix in _BAGS:
        return _bag_pose(path, topic)
    if topic is not None:
        raise BadInput(f"{path}: --topic is for a ROS bag; a CSV's columns are x, y, theta[, phi]")
    return _csv_pose(path)


def _csv_pose(path: Path) -> list[float]:
    text = read_bytes(path, MAX_POSE_FILE_BYTES).decode("utf-8", errors="replace")
    rows = [row for row in csv.reader(io.StringIO(text)) if row and any(cell.strip() for cell in row)]
    if len(rows) < 2:
        raise BadInput(f"{path}: needs a header (x, y, theta[, phi]) and at least one row of numbers")
    header = [name.strip().lower() for name in rows[0]]
    names = ["x", "y", "theta" if "theta" in header else "yaw"] + (["phi"] if "phi" in header else [])
    missing = [name for name in names if name not in header]
    if missing:
        raise BadInput(f"{path}: its header {rows[0]} has no column {missing[0]!r} (x, y, theta or yaw, [phi])")
    last = rows[-1]
    values = []
    for name in names:
        index = header.index(name)
        cell = last[index].strip() if index < len(last) else ""
        try:
            value = float(cell)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise BadInput(f"{path}: the last row's {name} is {cell!r}, not a finite number")
        values.append(value)
    return values


def _bag_pose(path: Path, topic: str | None) -> list[float]:
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise BadInput(f'{path}: a ROS bag needs rosbags: pip install "ilc-steering[rosbags]"') from None
    bag = path.parent if path.is_file() and path.suffix in (".mcap", ".db3") else path
    try:
        with AnyReader([bag]) as reader:
            poses = [c for c in reader.connections if c.msgtype in POSE_TYPES]
            if topic is not None:
                chosen = [c for c in reader.connections if c.topic == topic]
                if not chosen:
                    topics = sorted({c.topic for c in reader.connections})
                    raise BadInput(f"{path}: no topic {topic!r}; it has {topics}")
                if chosen[0].msgtype not in POSE_TYPES:
                    raise BadInput(f"{path}: topic {topic!r} is a {chosen[0].msgtype}, not one of {list(POSE_TYPES)}")
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
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    values = [float(pose.position.x), float(pose.position.y), yaw]
    if not all(math.isfinite(v) for v in values):
        raise BadInput(f"{path}: the last pose {values} is not finite")
    return values
