"""Policies as controllers: what an agent senses (the observation), how its action becomes a
setpoint, and the numerics of the built-in scripted policy (registered, like every policy, through
the hook ``swarmscene_register_policies``; ``plugins/policy/``). Shared by the ``policy`` avoidance
plugin and :mod:`swarmscene.env`, so a policy trained in the environment sees exactly the same
inputs when it flies as a plugin.
"""
