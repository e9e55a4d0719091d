"""``session record --pose-file``: the last pose of a CSV, or of a ROS 2 / ROS 1 bag that ``rosbags``
itself writes (odometry, a stamped pose, one with covariance); a file that cannot say a pose is
refused in one line naming it."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from ilc_steering.pose_files import final_pose

POSES = [(0.0, 0.0, 0.0), (0.5, 0.2, 0.3), (1.02, 0.43, 0.71)]
"""A trajectory's poses (x [m], y [m], yaw [rad]); the last is where the robot stopped."""


def test_a_csv_gives_its_last_row(tmp_path: Path) -> None:
    path = tmp_path / "poses.csv"
    path.write_text("t,x,y,theta\n" + "".join(f"{i},{x},{y},{t}\n" for i, (x, y, t) in enumerate(POSES)) + "\n")
    assert final_pose(path) == [1.02, 0.43, 0.71]
    path.write_text("yaw,y,x,phi\n0.71,0.43,1.02,0.05\n")
    assert final_pose(path) == [1.02, 0.43, 0.71, 0.05]


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("x,y\n1,2\n", "no column 'yaw'"),
        ("x,y,theta\n", "at least one row"),
        ("x,y,theta\n1,nan,0\n", "the last row's y is 'nan'"),
        ("x,y,theta\n1,2\n", "the last row's theta is ''"),
    ],
)
def test_a_csv_that_cannot_say_a_pose_is_refused_naming_it(tmp_path: Path, text: str, says: str) -> None:
    path = tmp_path / "poses.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"{path}.*{says}"):
        final_pose(path)


def _quaternion(typestore, yaw: float):  # type: ignore[no-untyped-def]
    return typestore.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def _message(typestore, msgtype: str, pose: tuple[float, float, float]):  # type: ignore[no-untyped-def]
    types = typestore.types
    stamp = types["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
    ros1 = "seq" in types["std_msgs/msg/Header"].__dataclass_fields__  # ROS 1's header counts its messages
    header = types["std_msgs/msg/Header"](**({"seq": 0} if ros1 else {}), stamp=stamp, frame_id="map")
    x, y, yaw = pose
    p = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=_quaternion(typestore, yaw)
    )
    covariance = __import__("numpy").zeros(36)
    with_covariance = types["geometry_msgs/msg/PoseWithCovariance"](pose=p, covariance=covariance)
    if msgtype == "geometry_msgs/msg/PoseStamped":
        return types[msgtype](header=header, pose=p)
    if msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
        return types[msgtype](header=header, pose=with_covariance)
    twist = types["geometry_msgs/msg/TwistWithCovariance"](
        twist=types["geometry_msgs/msg/Twist"](
            linear=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
            angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
        ),
        covariance=covariance,
    )
    return types[msgtype](header=header, child_frame_id="base_link", pose=with_covariance, twist=twist)


def write_bag(path: Path, msgtype: str, ros1: bool, topics: tuple[str, ...] = ("/odom",)) -> Path:
    """A bag that rosbags writes: ``POSES`` on each of ``topics`` (a ROS 1 ``.bag`` or a ROS 2 folder)."""
    from rosbags.typesys import Stores, get_typestore

    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        store = get_typestore(Stores.ROS1_NOETIC)
        bag = path.with_suffix(".bag")
        with Writer1(bag) as writer:
            for topic in topics:
                connection = writer.add_connection(topic, msgtype, typestore=store)
                for k, pose in enumerate(POSES):
                    data = store.serialize_ros1(_message(store, msgtype, pose), msgtype)
                    writer.write(connection, (k + 1) * 10**8, data)
        return bag
    from rosbags.rosbag2 import Writer

    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(path, version=8) as writer:
        for topic in topics:
            connection = writer.add_connection(topic, msgtype, typestore=store)
            for k, pose in enumerate(POSES):
                writer.write(connection, (k + 1) * 10**8, store.serialize_cdr(_message(store, msgtype, pose), msgtype))
    return path


@pytest.mark.extra("rosbags")
@pytest.mark.parametrize("ros1", [False, True], ids=["ros2", "ros1"])
@pytest.mark.parametrize(
    "msgtype", ["nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped"]
)
def test_a_bag_gives_the_last_pose_of_its_topic(tmp_path: Path, msgtype: str, ros1: bool) -> None:
    bag = write_bag(tmp_path / "run", msgtype, ros1)
    assert final_pose(bag) == pytest.approx([1.02, 0.43, 0.71], abs=1e-12)


@pytest.mark.extra("rosbags")
def test_a_bag_of_two_pose_topics_needs_one_named(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "run", "nav_msgs/msg/Odometry", False, ("/odom", "/mocap"))
    with pytest.raises(ValueError, match=r"2 pose topics \['/mocap', '/odom'\]; say which with --topic"):
        final_pose(bag)
    assert final_pose(bag, "/mocap") == pytest.approx([1.02, 0.43, 0.71], abs=1e-12)
    with pytest.raises(ValueError, match="no topic '/gps'"):
        final_pose(bag, "/gps")


@pytest.mark.extra("rosbags")
def test_a_folder_that_is_not_a_bag_is_refused_naming_it(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="cannot read it as a ROS bag"):
        final_pose(tmp_path / "empty")
