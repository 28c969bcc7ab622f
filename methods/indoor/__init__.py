"""Thesis chapter 5 (indoor swarming): line-of-sight sensing, the graphs G_s, G_n, G_sigma with
edge deactivation (eq. 5.15-5.22), ranks (eq. 5.23-5.29), follower and leader control
(eq. 5.30-5.44, Table 5.1) and the corridor and building maps. Used by the ``indoor_swarm``
formation and the ``potential_barrier`` avoidance."""
