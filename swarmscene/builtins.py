"""The built-in plugin modules, registered exactly like third-party ones (by module name).

Add a module here when you add a built-in algorithm; ``tests/core/test_contract.py`` checks that
every module in ``plugins/`` is listed, so one cannot be forgotten.
"""

BUILTIN_PLUGINS: tuple[str, ...] = (
    "swarmscene.plugins.dynamics.single_integrator",
    "swarmscene.plugins.dynamics.double_integrator",
    "swarmscene.plugins.formation.static_shape",
    "swarmscene.plugins.avoidance.none",
    "swarmscene.plugins.avoidance.potential",
    "swarmscene.plugins.avoidance.cem",
)
