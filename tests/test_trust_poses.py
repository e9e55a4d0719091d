"""A pose handed over by hand, as issue 64 found them misread: a CSV with a byte order mark, a CSV of a
hundred megabytes, a trailer's pose file, a bag with no pose topic, a quaternion of no length. Each is
read as the robot's pose or refused in one line naming the file and what it lacks."""

from __future__ import annotations

import math
import tracemalloc
from pathlib import Path

import pytest

from ilc_steering.config import load_config
from ilc_steering.core.robots.car import CAR
from ilc_steering.pose_files import MAX_ROW_BYTES, final_pose, typed_pose

TRAILER = load_config("trailer_bay").plant.kind
UNICYCLE = load_config("unicycle_parking").plant.kind


def test_a_csv_with_a_byte_order_mark_is_read(tmp_path: Path) -> None:
    path = tmp_path / "poses.csv"
    path.write_bytes("x,y,theta\n0,0,0\n1.02,0.43,-1e-05\n".encode("utf-8-sig"))
    assert final_pose(path) == [1.02, 0.43, -1e-05]


def test_a_csv_of_many_megabytes_is_read_from_its_ends(tmp_path: Path) -> None:
    path = tmp_path / "poses.csv"
    row = b"0.5,0.2,0.3,0.01\n"
    with path.open("wb") as file:
        file.write(b"x,y,theta,phi\n")
        file.write(row * ((24 << 20) // len(row)))
        file.write(b"1.02,0.43,0.71,0.05\n\n")
    tracemalloc.start()
    try:
        assert final_pose(path) == [1.02, 0.43, 0.71, 0.05]
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 4 * MAX_ROW_BYTES  # its two ends, not its 24 MB (a 100 MB one was a MemoryError)


@pytest.mark.slow  # over 2.5 s: the README's test command stays under 5 min
def test_a_csv_whose_last_row_is_beyond_what_is_read_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "poses.csv"
    path.write_bytes(b"x,y,theta\n1,2,3\n" + b"\n" * (MAX_ROW_BYTES + 10))
    with pytest.raises(ValueError, match="hold no row of numbers"):
        final_pose(path)


def test_a_trailers_pose_file_names_the_trailers_coordinates(tmp_path: Path) -> None:
    path = tmp_path / "poses.csv"
    path.write_text("t,x1,y1,theta1,phi,delta\n9,1.0,0.5,0.1,0.02,-0.03\n")
    assert final_pose(path, kind=TRAILER) == [1.0, 0.5, 0.1, 0.02, -0.03]
    path.write_text("x,y,theta,phi\n1,0.5,0.1,0.02\n")  # a car's file for a trailer
    with pytest.raises(ValueError, match=r"no column 'x1'"):
        final_pose(path, kind=TRAILER)
    path.write_text("x1,y1,θ1,φ,δ\n1,0.5,0.1,0.02,-0.03\n")  # the Greek letters, as the labels have them
    assert final_pose(path, kind=TRAILER) == [1.0, 0.5, 0.1, 0.02, -0.03]


def test_a_typed_pose_is_refused_naming_the_robots_coordinates() -> None:
    with pytest.raises(ValueError, match=r"--final needs 5 finite numbers \(x1, y1, θ1, φ, δ; world frame\)"):
        typed_pose([1.0, 0.5, 0.1, 0.02], TRAILER, [0.0] * 5, "--final")
    assert typed_pose([1.0, 0.5, 0.1], CAR, [9.0, 9.0, 9.0, 0.25], "--final") == [1.0, 0.5, 0.1, 0.25]
    with pytest.raises(ValueError, match=r"needs 3 finite numbers \(x, y, θ; world frame\)"):
        typed_pose([1.0, 0.5], UNICYCLE, [0.0] * 3, "--final")


def test_a_bag_cannot_give_a_trailers_pose(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"a bag's pose is x, y, a heading; this robot's is x1, y1, θ1, φ, δ"):
        final_pose(tmp_path / "run.bag", kind=TRAILER)


def _bag(path: Path, msgtype: str, topic: str, orientation: tuple[float, float, float, float]) -> Path:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    x, y, z, w = orientation
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=0.0),
        orientation=types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
    )
    header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="m")
    message = types[msgtype](header=header, pose=pose) if msgtype.endswith("PoseStamped") else None
    if message is None:  # a topic of another type: no pose
        message = types["std_msgs/msg/String"](data="hello")
    with Writer(path, version=8) as writer:
        connection = writer.add_connection(topic, msgtype, typestore=store)
        writer.write(connection, 10**8, store.serialize_cdr(message, msgtype))
    return path


@pytest.mark.extra("rosbags")
def test_a_bag_with_no_pose_topic_says_so_and_lists_its_topics(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "run", "std_msgs/msg/String", "/chatter", (0.0, 0.0, 0.0, 1.0))
    with pytest.raises(
        ValueError, match=r"no topic of a pose type .*; its topics: \[\('/chatter', 'std_msgs/msg/String'\)\]"
    ):
        final_pose(bag)


@pytest.mark.extra("rosbags")
@pytest.mark.parametrize(
    ("orientation", "yaw"),
    [((0.0, 0.0, 0.0, 0.0), None), ((0.0, 0.0, 2 * math.sin(0.35), 2 * math.cos(0.35)), 0.7)],
    ids=["no length", "twice the length"],
)
def test_a_quaternion_is_an_orientation_only_if_it_has_a_length(tmp_path: Path, orientation, yaw) -> None:
    bag = _bag(tmp_path / "run", "geometry_msgs/msg/PoseStamped", "/pose", orientation)
    if yaw is None:
        with pytest.raises(ValueError, match="orientation is no rotation"):
            final_pose(bag)
    else:
        assert final_pose(bag) == pytest.approx([1.0, 2.0, yaw], abs=1e-12)
