"""Named policies: a policy maps observations (N, D) to normalised actions (N, 3) in [-1, 1].

A policy is made by a factory ``factory(layout, spec, **options) -> policy`` where ``layout`` is the
:class:`~swarmscene.methods.policy.observation.ObservationLayout`, ``spec`` the
:class:`~swarmscene.methods.policy.actions.ActionSpec` and ``options`` the plugin's
``policy_options``; ``policy(obs)`` is called once per guidance tick with every agent's row.

Factories are found by name: the built-in scripted ones below, then the entry-point group
``swarmscene.policies`` of installed packages (a trained network wrapped by its own package)::

    [project.entry-points."swarmscene.policies"]
    my_ppo = "my_package.policy:make_policy"

A name offered twice is an error naming both sources; an unknown name lists the valid ones.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any

import numpy as np

from .actions import ActionSpec
from .observation import ObservationLayout

POLICY_GROUP = "swarmscene.policies"
Policy = Callable[[np.ndarray], np.ndarray]


class SeekReference:
    """A scripted policy: fly to the formation's reference, pushed off close neighbours and obstacles.

    Desired velocity, from the observation only:
        v_d = v_ref + k_p (p_ref - p_i)
              - k_r sum_j (1 - |d_ij| / r) d_ij / |d_ij|     over neighbours with |d_ij| < r
              - k_r (1 - c_i / r) n_i                         when the clearance c_i < r
    (d_ij = p_j - p_i, n_i the unit direction to the nearest obstacle), then scaled to the action:
    velocity actions a = v_d / max_speed; acceleration actions a = (v_d - v_i) / (T_s max_accel).
    """

    def __init__(self, layout: ObservationLayout, spec: ActionSpec, gain: float = 1.0,
                 repulsion: float = 2.0, radius: float = 1.0) -> None:
        if gain < 0 or repulsion < 0 or radius <= 0:
            raise ValueError("seek_reference: gain and repulsion must be >= 0 and radius > 0 "
                             f"(got gain={gain}, repulsion={repulsion}, radius={radius})")
        self.layout, self.spec = layout, spec
        self.gain, self.repulsion, self.radius = gain, repulsion, radius

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        f = self.layout.split(np.asarray(obs, dtype=float))
        desired = f["ref_vel"] + self.gain * f["ref_offset"] * f["ref_mask"]
        d = f["nbr_pos"]
        dist = np.linalg.norm(d, axis=2)
        close = (f["nbr_mask"] > 0) & (dist < self.radius) & (dist > 0)
        weight = np.where(close, (1.0 - dist / self.radius) / np.where(dist > 0, dist, 1.0), 0.0)
        desired -= self.repulsion * np.einsum("nk,nkc->nc", weight, d)
        clearance = f["obs_clearance"][:, 0]
        wall = (f["obs_mask"][:, 0] > 0) & (clearance < self.radius)
        push = np.where(wall, 1.0 - np.maximum(clearance, 0.0) / self.radius, 0.0)
        desired -= self.repulsion * push[:, None] * f["obs_dir"]
        spec = self.spec
        if spec.kind == "velocity":
            action = desired / spec.max_speed
        else:
            action = (desired - f["own_vel"]) / (spec.guidance_period * spec.max_accel)
        return np.clip(action, -1.0, 1.0).astype(np.float32)


BUILTIN_POLICIES: dict[str, Callable[..., Policy]] = {"seek_reference": SeekReference}


def policy_factories() -> dict[str, tuple[Callable[..., Policy] | Any, str]]:
    """Every policy factory by name, with where it comes from (entry points loaded lazily)."""
    found: dict[str, tuple[Any, str]] = {name: (f, "swarmscene") for name, f in BUILTIN_POLICIES.items()}
    for ep in entry_points(group=POLICY_GROUP):
        source = f"{ep.dist.name if ep.dist is not None else 'unknown'}:{ep.value}"
        if ep.name in found:
            raise ValueError(f"policy {ep.name!r} offered twice: by {found[ep.name][1]} and by {source}")
        found[ep.name] = (ep, source)
    return found


def make_policy(name: str, layout: ObservationLayout, spec: ActionSpec, options: dict[str, Any]) -> Policy:
    """The policy registered as ``name``, built with ``options``; unknown names list the valid ones."""
    factories = policy_factories()
    if name not in factories:
        raise ValueError(f"unknown policy {name!r} (valid: {', '.join(sorted(factories))})")
    factory = factories[name][0]
    if hasattr(factory, "load") and hasattr(factory, "group"):  # an entry point
        factory = factory.load()
    return factory(layout, spec, **options)
