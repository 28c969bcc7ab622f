"""The built-in plugin modules, registered exactly like third-party ones (by module name).

Add a module here when you add a built-in algorithm; ``tests/test_contract.py`` checks that every
module in ``plugins/`` that registers a class is listed, so one cannot be forgotten.
"""

BUILTIN_PLUGINS: tuple[str, ...] = (
    # dynamics: how agents move
    "swarmscene.plugins.dynamics.single_integrator",
    "swarmscene.plugins.dynamics.double_integrator",
    "swarmscene.plugins.dynamics.quadrotor",
    # formation: where agents should be
    "swarmscene.plugins.formation.static_shape",
    "swarmscene.plugins.formation.indoor_swarm",
    "swarmscene.plugins.formation.virtual_rigid_body",
    "swarmscene.plugins.formation.hex_lattice",
    "swarmscene.plugins.formation.outdoor_mission",
    "swarmscene.plugins.formation.reynolds_flocking",
    "swarmscene.plugins.formation.antipodal_swap",
    "swarmscene.plugins.formation.recorded",
    # avoidance: how they stay safe
    "swarmscene.plugins.avoidance.none",
    "swarmscene.plugins.avoidance.potential",
    "swarmscene.plugins.avoidance.cem",
    "swarmscene.plugins.avoidance.potential_barrier",
    "swarmscene.plugins.avoidance.apf_navigation",
    "swarmscene.plugins.avoidance.policy",
    "swarmscene.plugins.avoidance.orca",
    "swarmscene.plugins.avoidance.cbf",
    # disturbance: what the world does to them (the phases in core/disturbances/)
    "swarmscene.plugins.disturbance.constant_wind",
    "swarmscene.plugins.disturbance.gust",
    "swarmscene.plugins.disturbance.dryden",
    "swarmscene.plugins.disturbance.sensing_noise",
    "swarmscene.plugins.disturbance.comm_delay",
    "swarmscene.plugins.disturbance.packet_loss",
    "swarmscene.plugins.disturbance.downwash",
    "swarmscene.plugins.disturbance.ground_effect",
    "swarmscene.plugins.disturbance.drag",
    "swarmscene.plugins.disturbance.battery",
    "swarmscene.plugins.disturbance.radio",
    # event: what an event does to its agents (semantics in core/events.py)
    "swarmscene.plugins.event.hover",
    "swarmscene.plugins.event.comm_loss",
    "swarmscene.plugins.event.stuck",
    "swarmscene.plugins.event.drift",
    "swarmscene.plugins.event.motor_failure",
    # generator: obstacle maps from parameters (geometry in methods/maps/)
    "swarmscene.plugins.generator.corridor",
    "swarmscene.plugins.generator.building",
    "swarmscene.plugins.generator.obstacle_field",
    # policy: observations to actions (avoidance.policy; numerics in methods/policy/)
    "swarmscene.plugins.policy.seek_reference",
    "swarmscene.plugins.policy.entry_point_group",
    # observer: metrics a scenario asks for by name (observers=[swarmlab]; numerics in methods/)
    "swarmscene.plugins.observer.swarmlab",
)
