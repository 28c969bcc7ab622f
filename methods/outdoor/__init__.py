"""Thesis chapter 4 (outdoor swarming): the hexagonal formation pattern (eq. 4.3-4.12), each
agent's swarm map, APF navigation with flight levels (eq. 4.21-4.28) and the leader-follower
mission workflow (section 4.3.1, eq. 4.1-4.2: :mod:`.mission`). Used by the ``hex_lattice`` and
``outdoor_mission`` formations and the ``apf_navigation`` avoidance."""
