"""The per-tick code of small swarms as it was before issue #25's lean tick, kept as the oracle of
the leaner forms, which must give the same values bit for bit (presets stay bit-identical).

Each function is the old body, written against today's objects (the same laws, gains, paths and
offsets), so a test can run old and new side by side on one state.
"""

from __future__ import annotations

import numpy as np

from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.methods.quadrotor.thesis_controllers import _FAMILY, _POSITION, _TRACKER, _VELOCITY


def dense_pair_dist2(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair's squared distance, one pass per axis (core/vectors.py before #25)."""
    i, j = np.triu_indices(len(points), 1)
    d2 = np.zeros(i.size)
    for k in range(points.shape[1]):
        diff = points[j, k] - points[i, k]
        d2 += diff * diff
    return i, j, d2


def clip_norm(v: np.ndarray, limit) -> np.ndarray:
    norm = np.sqrt(np.einsum("...i,...i->...", v, v))[..., None]
    return v * np.minimum(1.0, limit / np.maximum(norm, 1e-300))


def sat(a: np.ndarray, u_sat) -> np.ndarray:
    return np.clip(a, -u_sat, u_sat)


def velocity_limiter(u_inf, v, v_lim, K_lim, eps_lim):
    v_lim = np.asarray(v_lim, dtype=float)
    if v_lim.ndim == 1:
        v_lim = v_lim[:, None]
    u_plus = -K_lim * (v - v_lim)
    u_minus = -K_lim * (v + v_lim)
    u_lim = np.where(v > 0.0, np.minimum(u_inf, u_plus), np.maximum(u_inf, u_minus))
    return np.where(v_lim > eps_lim, u_lim, -K_lim * v)


def thesis_step(ctrl, mode, r, v, r_ref, v_ref, u_ref, v_lim=None) -> np.ndarray:
    """ThesisController.step before #25: all three laws computed for every agent, then selected;
    every law's integral advanced under its mask."""
    family = _FAMILY[mode]
    ctrl._restart(family, r, v)
    is_vel = family == _VELOCITY
    is_pos = family == _POSITION
    u_inf = np.where(
        is_vel[:, None],
        ctrl.velocity.unbounded(v, v_ref),
        np.where(is_pos[:, None], ctrl.position.unbounded(r, v, r_ref),
                 ctrl.tracker.unbounded(r, v, r_ref, v_ref, u_ref)),
    )
    u_cmd = u_inf
    if v_lim is not None:
        u_cmd = np.where(is_vel[:, None], u_inf, velocity_limiter(u_inf, v, v_lim, ctrl.K_lim, ctrl.eps_lim))
    u = sat(u_cmd, ctrl.u_sat)
    ctrl.velocity.integrate(v, v_ref, u_inf, u, is_vel)
    ctrl.position.integrate(r, r_ref, u_inf, u, is_pos)
    ctrl.tracker.integrate(r, r_ref, u_inf, u, family == _TRACKER)
    return u


def double_integrator_control(dyn, world, sp: Setpoints) -> np.ndarray:
    """DoubleIntegrator.control before #25 (on the oracle controller step): the input u."""
    healthy = world.healthy
    mode = np.where(healthy, sp.mode, Mode.HOLD)
    r_ref = np.where(healthy[:, None], sp.pos, world.pos)
    v_ref = sp.vel if dyn.params.v_max is None else np.clip(sp.vel, -dyn.params.v_max, dyn.params.v_max)
    return thesis_step(dyn.controller, mode, world.pos, world.vel, r_ref, v_ref, sp.acc, dyn.params.v_max)


def double_integrator_step(pos, vel, u, dt) -> None:
    pos += vel * dt + 0.5 * u * dt * dt
    vel += u * dt


def single_integrator_u(params, world, sp: Setpoints) -> np.ndarray:
    correction = params.gain * (sp.pos - world.pos)
    u = np.where((sp.mode == Mode.VELOCITY)[:, None], sp.vel, sp.vel + correction)
    u = np.where((sp.mode == Mode.HOLD)[:, None], correction, u)
    return clip_norm(u, params.u_max)


def static_shape_setpoints(formation, world) -> Setpoints:
    """StaticShape.setpoints before #25, on a formation whose slots are already assigned (it does
    not re-assign: call it on a copy of the formation's state)."""
    center, velocity, leg, _ = formation.path.at(world.t)
    heading = formation._heading(leg)
    c, s = np.cos(heading), np.sin(heading)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    slots = center + formation.offsets @ rot.T
    sp = Setpoints.hold(world.pos)
    active = formation.slot_of >= 0
    sp.mode[active] = Mode.TRACK
    sp.pos[active] = slots[formation.slot_of[active]]
    sp.vel[active] = velocity
    sp.yaw[:] = heading
    return sp


def potential_adjust(potential, world, sensing, sp: Setpoints) -> Setpoints:
    """Potential.adjust before #25 (pairs and obstacles from the same sensing)."""
    from swarmscene.plugins.avoidance.potential import barrier

    p, d_s = potential.params, potential.ctx.separation_limit
    v = np.zeros_like(world.pos)
    d_range = p.influence * max(d_s, 1e-3)
    pairs = sensing.pairs(d_range)
    if len(pairs):
        i, j = pairs[:, 0], pairs[:, 1]
        delta = world.pos[i] - world.pos[j]
        d = np.linalg.norm(delta, axis=1)
        push = (p.v_max * barrier(d, d_s, d_range) / np.maximum(d, 1e-9))[:, None] * delta
        np.add.at(v, i, push)
        np.add.at(v, j, -push)
    if not sensing.environment.empty:
        obstacle = potential._obstacle_repulsion(world, sensing)
        v += np.zeros_like(world.pos) if obstacle is None else obstacle
    v_rep = clip_norm(v, p.v_max)
    v_rep[~world.healthy] = 0.0
    out = sp.copy()
    out.vel += v_rep
    moving = out.mode != Mode.VELOCITY
    out.pos[moving] += p.lookahead * v_rep[moving]
    return out
