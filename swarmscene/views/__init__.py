"""Views of a run: what it prints, draws, streams, replays and exports.

    summary.py          the progress line, the run's warnings, the printed summary and its verdicts
    plots.py            the figures and the animation (``output.plots``, ``output.animation``)
    live.py             the live view during a run (``output.live``, Rerun)
    replay.py           a recorded run replayed in Rerun (``python -m swarmscene.views.replay``)
    mcap_bag.py         the ROS 2 bag of a run (``output.mcap``; docs/ros.md), written with
    mcap_file.py        the MCAP container; foxglove_layout.json: its Foxglove layout
    export.py           the Crazyflie export (``python -m swarmscene.views.export``), whose bundle
    crazyswarm2_show.py carries this program, run on the Crazyswarm2 side
    writers.py          the optional outputs a run asked for, as writer functions

Imports run one way: the entry points, the sweeps and the tools import this package; it imports
the run directory's package (:mod:`swarmscene.runs`) and the engine, never the entry points.
"""
