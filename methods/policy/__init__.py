"""Policies as controllers: what an agent senses (the observation), how its action becomes a
setpoint, and the registry of named policies (built-in scripted ones and the entry-point group
``swarmscene.policies``). Shared by the ``policy`` avoidance plugin and :mod:`swarmscene.env`, so a
policy trained in the environment sees exactly the same inputs when it flies as a plugin.
"""
