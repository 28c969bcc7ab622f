"""World state: one array per field, agents along the first axis.

World frame (the one frame of the engine): right-handed, x east, y north, z up, metres,
seconds, radians. The thesis works in North-East-Down; its plugins convert at their boundary
(x_world = y_NED, y_world = x_NED, z_world = -z_NED). The CEM paper's plane is the world x-y
plane; the VRB paper is already z-up.

A failed vehicle is masked (``healthy[i] = False``), never deleted, so agent indices are stable
for the whole run and equal the agent ids used in config (0 .. N-1).
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

import numpy as np


class Role(IntEnum):
    """Role of an agent in ``WorldState.role``."""

    FOLLOWER = 0
    LEADER = 1


@dataclass
class WorldState:
    """State of every agent at the current time.

    Attributes:
        t: simulated time, s.
        pos: positions, shape (N, 3), m, world frame.
        vel: velocities, shape (N, 3), m/s, world frame.
        healthy: (N,) bool; False once a failure event hit the agent (it then holds still).
        comm_ok: (N,) bool; False once the agent lost its radio (``comm_loss`` event): it drops
            out of the communication graph but keeps flying.
        role: (N,) int8, values of :class:`Role`.
        quat: orientation quaternions (w, x, y, z), body to world, shape (N, 4); ``None`` unless
            the dynamics model has attitude.
        omega: body angular rates, shape (N, 3), rad/s, body frame; ``None`` unless the dynamics
            model has attitude.
        rotor_speed: (N, 4) rad/s, for rotor-level models, else ``None``.
        acc: (N, 3) m/s^2, world frame: the acceleration input the dynamics model applied this
            tick (thesis u, eq. 3.21), for models with one; ``None`` otherwise. Formations use it
            as the leader's feed-forward (thesis eq. 4.11).
        wind: (N, 3) m/s, world frame: the air's velocity at each agent during the current physics
            step (the ``disturbances`` wind phase sets it before ``dynamics.step``); ``None`` when
            no wind model is declared. A model with ``wind_coupling = "integrated"`` reads it.
        wind_moment_arm: height of the centre of pressure above the centre of gravity, m (the
            wind models' ``moment_arm``): models with attitude take the wind force's moment there.
        force: (N, 3) m/s^2, world frame: the force per unit mass of the ``disturbances`` force
            phase (downwash, ground effect, drag, a battery's limit) during the current physics
            step; ``None`` when no force model is declared.
    """

    t: float
    pos: np.ndarray
    vel: np.ndarray
    healthy: np.ndarray
    comm_ok: np.ndarray
    role: np.ndarray
    quat: np.ndarray | None = None
    omega: np.ndarray | None = None
    rotor_speed: np.ndarray | None = None
    acc: np.ndarray | None = None
    wind: np.ndarray | None = None
    wind_moment_arm: float = 0.0
    force: np.ndarray | None = None

    @classmethod
    def at_rest(cls, pos: np.ndarray, leader: int | None = None) -> WorldState:
        """A swarm at rest at ``pos`` (N, 3), all healthy, agent ``leader`` (if any) leading."""
        pos = np.array(pos, dtype=float, copy=True)
        n = pos.shape[0]
        role = np.full(n, Role.FOLLOWER, dtype=np.int8)
        if leader is not None:
            role[leader] = Role.LEADER
        return cls(
            t=0.0,
            pos=pos,
            vel=np.zeros_like(pos),
            healthy=np.ones(n, dtype=bool),
            comm_ok=np.ones(n, dtype=bool),
            role=role,
        )

    @property
    def n(self) -> int:
        """Number of agents, healthy or not."""
        return self.pos.shape[0]

    @property
    def leader(self) -> int | None:
        """Index of the leader, or ``None`` when the swarm has none."""
        idx = np.flatnonzero(self.role == Role.LEADER)
        return int(idx[0]) if idx.size else None


BATCHED_FIELDS = ("pos", "vel", "quat", "omega", "rotor_speed")
"""The per-agent fields a :class:`WorldBatch` holds along its world axis."""


class WorldBatch:
    """B worlds of one composition, their per-agent state stored along a leading world axis.

    Each field of :data:`BATCHED_FIELDS` that the worlds have is one C-contiguous array of shape
    (B, N, k), and every world's own field is its slice ``array[b]``, a view: a plugin written for
    one world reads and writes its world as before, and a plugin's batched form
    (:meth:`~swarmscene.core.plugin.Dynamics.step_batch`) updates all B worlds with one array
    operation. ``models`` holds each world's instance of a plugin, in the worlds' order.

    A batch is built over the worlds that are still running; when one ends, the engine builds a
    new batch over the others (the ended world keeps its last state in the old arrays).

    Attributes:
        worlds: the B worlds (their ``pos`` etc. are views into this batch's arrays).
        pos, vel: (B, N, 3); ``quat`` (B, N, 4), ``omega`` (B, N, 3), ``rotor_speed`` (B, N, 4)
            when the worlds have them, else ``None``.
    """

    def __init__(self, worlds: list[WorldState]) -> None:
        self.worlds = list(worlds)
        self._tick_memo: dict[str, Any] = {}
        self._latched: dict[str, Any] = {}  # latch(): the coming tick's memo, until controlled()
        self._batch_memo: dict[str, Any] = {}
        # pack(): per names, the instances packed and, per name, the stacked array and its slices
        self._packed: dict[tuple[str, ...] | str, tuple[list[Any], dict[str, tuple[np.ndarray, list[np.ndarray]]]]] = {}
        for name in BATCHED_FIELDS:
            arrays = [getattr(world, name) for world in self.worlds]
            if any(a is None for a in arrays):
                setattr(self, name, None)
                continue
            stacked = np.stack(arrays)  # a copy: from now on the worlds' fields are its slices
            setattr(self, name, stacked)
            for world, view in zip(self.worlds, stacked, strict=True):
                setattr(world, name, view)

    pos: np.ndarray
    vel: np.ndarray
    quat: np.ndarray | None
    omega: np.ndarray | None
    rotor_speed: np.ndarray | None

    def controlled(self) -> None:
        """Say that every world's ``control`` ran (a new guidance tick): what batched forms keep
        per tick (:meth:`per_tick`) is made again at their next step. The engine calls it each
        tick; code that drives a batch itself (a test, a benchmark) calls it after the controllers."""
        self._tick_memo, self._latched = self._latched, {}

    def latch(self, key: str, value: Any) -> None:
        """Give the coming tick's :meth:`per_tick` ``key`` now: what a batched ``control_batch``
        already holds of the tick it latched (the instances' references it has just packed), so
        that the tick's steps do not gather it again from B instances. :meth:`controlled` makes it
        the tick's. Latch only what stays true after ``control_batch`` returns: not when it leaves
        worlds to their own ``control``, which may change it."""
        self._latched[key] = value

    def per_tick(self, key: str, make: Callable[[], Any]) -> Any:
        """``make()`` once per guidance tick (until :meth:`controlled`): what a batched form reads
        of the instances after their ``control`` (their commands stacked, whether their options
        agree), so that the physics sub-steps of a tick pay for it once, not B times per sub-step."""
        if key not in self._tick_memo:
            self._tick_memo[key] = make()
        return self._tick_memo[key]

    def per_batch(self, key: str, make: Callable[[], Any]) -> Any:
        """``make()`` once for this batch (its worlds and their instances, which a batch keeps
        until a world ends): what does not change while they fly, such as whether the instances'
        frozen options agree."""
        if key not in self._batch_memo:
            self._batch_memo[key] = make()
        return self._batch_memo[key]

    @property
    def size(self) -> int:
        """B, the number of worlds."""
        return len(self.worlds)

    def stack(self, name: str) -> np.ndarray:
        """A world field that the batch does not hold (``wind``, ``force``), stacked (B, N, k): a copy."""
        return np.stack([getattr(world, name) for world in self.worlds])

    def pack(self, models: list[Any], names: tuple[str, ...], key: str | None = None,
             together: bool = False) -> dict[str, np.ndarray]:
        """The per-agent arrays ``names`` of the worlds' plugin instances ``models``, as (B, N, k)
        arrays whose slices the instances then hold (like the worlds' fields).

        The first call stacks them and rebinds each instance's attribute to its slice, so an
        instance that writes its arrays in place (a controller latching references) writes into
        the batch; a later call returns the same arrays unless an instance has rebound one of
        them (reallocated it), in which case that name is stacked and rebound again. The arrays are
        kept under ``key`` (default: ``names``): a model that packs several lists of instances
        (one per controller law) gives each its own key, so that one does not unpack the other.
        ``together``: the instances rebind these arrays only all at once (an allocation), so the
        check that they still hold their slices reads the first name only (B instead of B x names
        attribute reads; a batch of 4,096 one-agent worlds packs 12 names per tick).
        """
        kept = names if key is None else key
        known = self._packed.get(kept)
        if known is None or known[0] != models:
            known = self._packed[kept] = (list(models), {})
        packed = known[1]
        if together and all(name in packed for name in names) and _holds(models, names[0], packed[names[0]]):
            return {name: packed[name][0] for name in names}
        for name in names:
            held = packed.get(name)
            if held is not None and _holds(models, name, held):
                continue
            stacked = np.stack([getattr(model, name) for model in models])
            views = list(stacked)
            for model, view in zip(models, views, strict=True):
                setattr(model, name, view)
            packed[name] = (stacked, views)
        return {name: packed[name][0] for name in names}


def _holds(models: list[Any], name: str, held: tuple[np.ndarray, list[np.ndarray]]) -> bool:
    """Whether every instance still holds, as ``name``, the slice :meth:`WorldBatch.pack` gave it
    (C loops: a few tens of ns an instance)."""
    return all(map(operator.is_, map(operator.attrgetter(name), models), held[1]))
