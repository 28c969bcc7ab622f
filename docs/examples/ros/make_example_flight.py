"""Write the example flight the ``recorded`` formation plays by default (methods/ros2/example_flight).

A stand-in for a lab's flight log, written the way a lab's tools write one (rosbags' rosbag2
writer, MCAP storage, metadata version 9), not by swarmscene: eight Crazyflies ``cf1``..``cf8``
an eighth of a turn apart on a 2 m circle (20 s a turn), rising and falling 0.3 m about 1.0 m, TF
``world`` -> ``cfK`` at 50 Hz for 20 s, one TFMessage per vehicle per sample as Crazyswarm2's
motion-capture node publishes them.

    python docs/examples/ros/make_example_flight.py methods/ros2/example_flight
"""

import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

RATE = 10.0  # Hz
DURATION = 20.0  # s
PERIOD = 20.0  # s, one turn
N = 8
EPOCH = 1_700_000_000  # s: stamps as a lab's clock gives them (2023-11-14), not from 0


def circle_wave(t: np.ndarray, k: int) -> np.ndarray:
    """(T, 3) m: vehicle k's position, an eighth of a turn ahead of vehicle k - 1 on a 2 m circle,
    rising and falling 0.3 m about 1.0 m twice a turn."""
    w = 2 * np.pi / PERIOD
    phase = w * t + k * 2 * np.pi / N
    return np.stack([2.0 * np.cos(phase), 2.0 * np.sin(phase), 1.0 + 0.3 * np.sin(2 * phase)], axis=1)


def main(out: Path) -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    TFMessage = store.types["tf2_msgs/msg/TFMessage"]
    TransformStamped = store.types["geometry_msgs/msg/TransformStamped"]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    Transform = store.types["geometry_msgs/msg/Transform"]
    Vector3 = store.types["geometry_msgs/msg/Vector3"]
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    t = np.arange(int(DURATION * RATE) + 1) / RATE
    paths = [circle_wave(t, k) for k in range(N)]
    with Writer(out, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        tf = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        for j, now in enumerate(t):
            ns = EPOCH * 10**9 + int(round(now * 1e9))
            for k in range(N):
                x, y, z = paths[k][j]
                stamped = TransformStamped(
                    Header(Time(sec=ns // 10**9, nanosec=ns % 10**9), "world"), f"cf{k + 1}",
                    Transform(Vector3(x=x, y=y, z=z), Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)))
                msg = TFMessage([stamped])
                writer.write(tf, ns, store.serialize_cdr(msg, "tf2_msgs/msg/TFMessage"))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
