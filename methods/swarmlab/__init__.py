"""SwarmLab's swarm performance metrics (Soria, Schiano, Floreano, "SwarmLab: a Matlab drone
swarm simulator", IROS 2020, section IV-C; ``math_tools/compute_swarm_performance.m``): safety,
order, union, algebraic connectivity and obstacle safety of one swarm state (:mod:`.metrics`)."""
