"""Named policies: a policy maps observations (N, D) to normalised actions (N, 3) in [-1, 1].

A policy is a registered class (:class:`~swarmscene.core.plugin.Policy`, hook
``swarmscene_register_policies``) built once per run as ``cls(params, layout, spec)``, where
``layout`` is the :class:`~swarmscene.methods.policy.observation.ObservationLayout`, ``spec`` the
:class:`~swarmscene.methods.policy.actions.ActionSpec` and ``params`` its validated ``Params`` (the
plugin's ``policy_options``); ``policy(obs)`` is called once per guidance tick with every agent's row.

This module holds the numerics of the built-in scripted policy (:func:`seek_reference_actions`,
registered by ``plugins/policy/seek_reference.py``) and the deprecated entry-point group
``swarmscene.policies`` (factories ``factory(layout, spec, **options) -> policy``), which still works
for one release, with a DeprecationWarning pointing to the hook (:func:`entry_point_policies`);
each of its policies is a :class:`FactoryPolicy` subclass held as a module attribute, so it pickles.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from functools import lru_cache
from importlib.metadata import entry_points
from typing import Any, ClassVar

import numpy as np
from pydantic import ConfigDict

from swarmscene.core.plugin import PluginParams, Policy

from .actions import ActionSpec
from .observation import ObservationLayout

POLICY_GROUP = "swarmscene.policies"
"""Deprecated entry-point group of policy factories (use the hook ``swarmscene_register_policies``)."""
PolicyFunction = Callable[[np.ndarray], np.ndarray]


def seek_reference_actions(layout: ObservationLayout, spec: ActionSpec, obs: np.ndarray, gain: float,
                           repulsion: float, radius: float) -> np.ndarray:
    """A scripted policy: fly to the formation's reference, pushed off close neighbours and obstacles.

    Desired velocity, from the observation only:
        v_d = v_ref + k_p (p_ref - p_i)
              - k_r sum_j (1 - |d_ij| / r) d_ij / |d_ij|     over neighbours with |d_ij| < r
              - k_r (1 - c_i / r) n_i                         when the clearance c_i < r
    (d_ij = p_j - p_i, n_i the unit direction to the nearest obstacle; k_p ``gain``, k_r
    ``repulsion``, r ``radius``), then scaled to the action: velocity actions a = v_d / max_speed;
    acceleration actions a = (v_d - v_i) / (T_s max_accel). Returns (N, 3) float32 in [-1, 1].
    """
    f = layout.split(np.asarray(obs, dtype=float))
    desired = f["ref_vel"] + gain * f["ref_offset"] * f["ref_mask"]
    d = f["nbr_pos"]
    dist = np.linalg.norm(d, axis=2)
    close = (f["nbr_mask"] > 0) & (dist < radius) & (dist > 0)
    weight = np.where(close, (1.0 - dist / radius) / np.where(dist > 0, dist, 1.0), 0.0)
    desired -= repulsion * np.einsum("nk,nkc->nc", weight, d)
    clearance = f["obs_clearance"][:, 0]
    wall = (f["obs_mask"][:, 0] > 0) & (clearance < radius)
    push = np.where(wall, 1.0 - np.maximum(clearance, 0.0) / radius, 0.0)
    desired -= repulsion * push[:, None] * f["obs_dir"]
    if spec.command == "velocity":
        action = desired / spec.max_speed
    else:
        action = (desired - f["own_vel"]) / (spec.guidance_period * spec.max_accel)
    return np.clip(action, -1.0, 1.0).astype(np.float32)


def make_policy(cls: type[Policy], layout: ObservationLayout, spec: ActionSpec,
                options: dict[str, Any]) -> Policy:
    """The registered policy class ``cls`` built with ``options`` (validated by its ``Params``)."""
    return cls(cls.Params.model_validate(options), layout, spec)


class _FactoryOptions(PluginParams):
    """Options of a policy from the deprecated entry-point group: passed to its factory as given."""

    model_config = ConfigDict(extra="allow", frozen=True)


class FactoryPolicy(Policy):
    """A policy from the deprecated entry-point group ``swarmscene.policies``: the entry point's
    factory, loaded and called once per run with the layout, the action spec and the options.

    Each listed name is a subclass of this one (:func:`_factory_policy`) made a module attribute,
    so pickle finds it by name, as it finds any class (a launcher such as joblib or Ray pickles a
    scenario, whose validated options hold the policy's class); another process that unpickles it
    lists the group again (:func:`__getattr__`). An instance pickles if its factory's function does.
    """

    entry_point: ClassVar[Any]
    """The entry point whose factory builds the policy function."""
    Params = _FactoryOptions

    def __init__(self, params: PluginParams, layout: Any, spec: Any) -> None:
        super().__init__(params, layout, spec)
        self.function = self.entry_point.load()(layout, spec, **(params.model_extra or {}))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The factory-built function's actions for the observation rows."""
        return self.function(obs)


_FACTORY_POLICIES: dict[str, type[FactoryPolicy]] = {}
"""The classes made so far, by attribute name: one class per entry point for the whole process
(pickle checks that the class it finds by name is the one it was given)."""


def _attribute(name: str) -> str:
    """The module attribute that holds the class of policy ``name`` (pickle splits a class's
    qualified name at dots, which an entry-point name may hold)."""
    return "FactoryPolicy[" + name.replace("%", "%25").replace(".", "%2E") + "]"


def _factory_policy(name: str, ep: Any) -> type[FactoryPolicy]:
    """The :class:`FactoryPolicy` subclass of entry point ``ep`` (the same class every time the
    same entry point is listed)."""
    attribute = _attribute(name)
    cls = _FACTORY_POLICIES.get(attribute)
    if cls is None or cls.entry_point != ep:
        doc = f"Policy {name!r} from the entry-point group {POLICY_GROUP} (deprecated)."
        cls = type(attribute, (FactoryPolicy,), {
            "name": name, "entry_point": ep, "__doc__": doc, "__module__": __name__, "__qualname__": attribute})
        _FACTORY_POLICIES[attribute] = cls
    return cls


def __getattr__(attribute: str) -> type[FactoryPolicy]:
    """A policy class of the deprecated group, by its attribute name: what pickle asks for when it
    loads one in a process that has not listed the group yet (a launcher's worker)."""
    if attribute.startswith("FactoryPolicy[") and attribute not in _FACTORY_POLICIES:
        for ep in _listed(entry_points):
            if _attribute(ep.name) == attribute:
                _factory_policy(ep.name, ep)
    try:
        return _FACTORY_POLICIES[attribute]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {attribute!r}") from None


@lru_cache(maxsize=4)
def _listed(lister: Callable[..., Any]) -> tuple[Any, ...]:
    """The group's entry points, listed once per process (every plugin manager asks: every job of
    a sweep); keyed by the lister, so a test that replaces ``entry_points`` gets its own list."""
    return tuple(lister(group=POLICY_GROUP))


def entry_point_policies() -> list[type[Policy]]:
    """The policies of the deprecated group ``swarmscene.policies``, each wrapped as a Policy class;
    a DeprecationWarning names each one found (register a Policy subclass through the hook
    ``swarmscene_register_policies`` instead)."""
    found: list[type[Policy]] = []
    for ep in _listed(entry_points):
        source = f"{ep.dist.name if ep.dist is not None else 'unknown'}:{ep.value}"
        warnings.warn(
            f"policy {ep.name!r} ({source}) comes through the entry-point group {POLICY_GROUP}, "
            "deprecated: register a swarmscene.plugin.Policy subclass through the hook "
            "swarmscene_register_policies (docs/plugins.md)", DeprecationWarning, stacklevel=2)
        found.append(_factory_policy(ep.name, ep))
    return found
