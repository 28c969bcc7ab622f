"""Standard multi-robot collision-avoidance baselines (issue #14), importable without any plugin.

- :mod:`.halfplanes`: the closest allowed velocity in a speed disc cut by half-planes, for all
  agents in lock-step (RVO2's linear programs 1-3).
- :mod:`.orca`: Optimal Reciprocal Collision Avoidance (van den Berg, Guy, Lin, Manocha 2011).
- :mod:`.cbf`: safety barrier certificates (Wang, Ames, Egerstedt 2017; Borrmann et al. 2015).
- :mod:`.neighbours`, :mod:`.common`: neighbour tables and the preferred velocity of a setpoint.
"""
