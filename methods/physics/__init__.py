"""The physics a dense swarm meets (issue #37): downwash, ground effect, drag, a battery and a radio.

Each module holds one published model's numerics, vectorised over agents, with its source, its
symbols and its Crazyflie-class parameters (:mod:`.crazyflie`); the ``downwash``,
``ground_effect``, ``drag``, ``battery`` and ``radio`` disturbance plugins
(``plugins/disturbance/``) are thin adapters over them. docs/physics.md has the overview.
"""
