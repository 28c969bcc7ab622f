"""ROS 2 interoperability without a ROS install: CDR messages written with NumPy (``cdr.py``),
the message definitions a bag carries (``messages.py``), recordings read back from MCAP files and
rosbag2 folders (``bag.py``) and played back as reference paths (``playback.py``). Used by the
``output.mcap`` bag writer (swarmscene/views/mcap_bag.py) and the ``recorded`` formation."""
