"""The Foxglove layout's three panels drawn with matplotlib from a bag's decoded messages.

Not a Foxglove screenshot: a stand-in for docs/ros.md, made from what any ROS tool would read. The
messages are decoded by mcap-ros2-support (not by swarmscene): /tf (each vehicle's path, seen from
above), /swarmscene/obstacles and /swarmscene/keep_out (markers), /swarmscene/min_separation against
/swarmscene/separation_limit (the plot panel) and /rosout (the log panel).

    swarmscene events=lead_fails output.mcap=true hydra.run.dir=runs/lead_fails
    python docs/examples/ros/bag_picture.py runs/lead_fails/bag docs/gallery/ros_bag.png
"""

import sys
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402

LEVELS = {10: "DEBUG", 20: "INFO", 30: "WARN", 40: "ERROR", 50: "FATAL"}


def read(bag: Path) -> dict[str, list]:
    (mcap,) = sorted(bag.glob("*.mcap"))
    topics: dict[str, list] = {}
    with open(mcap, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
            topics.setdefault(channel.topic, []).append((message.log_time * 1e-9, decoded))
    return topics


def main(bag: Path, out: Path) -> None:
    topics = read(bag)
    fig = plt.figure(figsize=(13, 6.5))
    grid = fig.add_gridspec(2, 2, width_ratios=[1.35, 1], height_ratios=[1.1, 1])
    scene, plot, log = fig.add_subplot(grid[:, 0]), fig.add_subplot(grid[0, 1]), fig.add_subplot(grid[1, 1])

    # 3-D panel (from above): the /tf frames' paths, obstacles, keep-out discs
    for _, msg in topics.get("/swarmscene/obstacles", []):
        for marker in msg.markers:
            pts = np.array([[p.x, p.y] for p in marker.points]).reshape(-1, 3, 2)
            for tri in pts:
                scene.fill(tri[:, 0], tri[:, 1], color="0.6", alpha=0.5, lw=0)
    frames: dict[str, list] = {}
    for _, msg in topics["/tf"]:
        for tf in msg.transforms:
            frames.setdefault(tf.child_frame_id, []).append((tf.transform.translation.x, tf.transform.translation.y))
    for name, xy in frames.items():
        xy = np.array(xy)
        line, = scene.plot(xy[:, 0], xy[:, 1], lw=1.2, label=name)
        scene.plot(*xy[-1], "o", color=line.get_color(), ms=4)
    for _, msg in topics.get("/swarmscene/keep_out", []):
        for marker in msg.markers:
            scene.add_patch(plt.Circle((marker.pose.position.x, marker.pose.position.y), marker.scale.x / 2,
                                       color=(marker.color.r, marker.color.g, marker.color.b), alpha=0.35))
    scene.set_aspect("equal")
    scene.set_title("3D panel (from above): /tf world -> agent_i/base_link, markers", fontsize=10)
    scene.set_xlabel("x east (m)")
    scene.set_ylabel("y north (m)")
    scene.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0, -0.2), ncol=3)

    # plot panel: separation against its limit
    for topic, label, style in (("/swarmscene/min_separation", "min_separation.data", "-"),
                                ("/swarmscene/separation_limit", "separation_limit.data", "--")):
        t = [when for when, _ in topics[topic]]
        plot.plot(t, [msg.data for _, msg in topics[topic]], style, label=label)
    plot.set_title("Plot panel: /swarmscene/min_separation vs its limit (m)", fontsize=10)
    plot.set_xlabel("simulated time (s)")
    plot.legend(fontsize=8)

    # log panel: /rosout
    log.axis("off")
    lines = [f"{when:6.2f} s  {LEVELS.get(msg.level, msg.level):5s} {msg.msg}" for when, msg in topics["/rosout"]]
    wrapped = [textwrap.shorten(line, 110, placeholder=" ...") for line in lines]
    log.text(0, 1, "Log panel: /rosout\n\n" + "\n".join(wrapped), va="top", family="monospace", fontsize=6.5)
    fig.suptitle("The Foxglove layout's panels drawn with matplotlib from the decoded bag (not a Foxglove "
                 "screenshot)", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
