"""The setpoint record: the one interface every formation, avoidance and dynamics plugin shares.

A formation fills it each guidance tick, an avoidance method returns a safe copy of it, and the
dynamics model's controller turns it into motion. All arrays have agents along the first axis and
are in the world frame (see :mod:`swarmscene.core.state`).
"""

from __future__ import annotations

import operator
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import cast, overload

import numpy as np


class Mode(IntEnum):
    """How the controller should use an agent's setpoint (``Setpoints.mode``).

    POSITION: go to ``pos`` and stay there (``vel``, ``acc`` are feed-forward, usually zero).
    VELOCITY: fly at ``vel`` (``pos`` is ignored); e.g. APF navigation, flocking.
    TRACK: follow a moving target whose state is ``pos``, ``vel`` and whose input is ``acc``
        (thesis tracker control, eq. 3.41-3.44; flat outputs of a VRB trajectory).
    HOLD: keep still where the agent is (failed vehicles, agents waiting).
    """

    POSITION = 0
    VELOCITY = 1
    TRACK = 2
    HOLD = 3


def is_mode(mode: np.ndarray, *modes: Mode) -> np.ndarray:
    """Which agents' ``mode`` (N,) is one of ``modes``, (N,) bool. Compared as plain ints: numpy
    compares an array with an enum member about 5x slower (~2.5 us against 0.5 for six agents),
    which a per-world tick pays several times."""
    hit = mode == int(modes[0])
    for other in modes[1:]:
        hit |= mode == int(other)
    return hit


@dataclass
class Setpoints:
    """Per-agent references for this guidance tick.

    Attributes:
        mode: (N,) int8, values of :class:`Mode`.
        pos: (N, 3) m, reference position.
        vel: (N, 3) m/s, reference velocity (the command in VELOCITY mode, feed-forward otherwise).
        acc: (N, 3) m/s^2, feed-forward acceleration (the target's input in TRACK mode).
        yaw: (N,) rad, heading about world z (0 = facing +x).
        jerk: (N, 3) m/s^3 or ``None``; flat-output feed-forward for attitude-level controllers.
        snap: (N, 3) m/s^4 or ``None``; flat-output feed-forward for attitude-level controllers.
    """

    mode: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    yaw: np.ndarray
    jerk: np.ndarray | None = None
    snap: np.ndarray | None = None

    @classmethod
    def hold(cls, pos: np.ndarray, yaw: np.ndarray | None = None) -> Setpoints:
        """Every agent holds ``pos`` (N, 3) with zero feed-forward."""
        n = pos.shape[0]
        return cls(
            mode=np.full(n, int(Mode.HOLD), dtype=np.int8),  # an int: numpy converts an enum slowly
            pos=np.array(pos, dtype=float, copy=True),
            vel=np.zeros((n, 3)),
            acc=np.zeros((n, 3)),
            yaw=np.zeros(n) if yaw is None else np.array(yaw, dtype=float, copy=True),
        )

    def copy(self) -> Setpoints:
        """A deep copy, so an avoidance method can edit without touching the formation's arrays."""
        # The constructor, not dataclasses.replace (twice its cost, on every avoidance's tick).
        return type(self)(
            self.mode.copy(), self.pos.copy(), self.vel.copy(), self.acc.copy(), self.yaw.copy(),
            None if self.jerk is None else self.jerk.copy(),
            None if self.snap is None else self.snap.copy(),
        )

    @property
    def n(self) -> int:
        """N, the agents these setpoints command."""
        return self.pos.shape[0]


class SetpointBatch(Sequence[Setpoints]):
    """B worlds' setpoints as one record over their stacked B x N agents.

    What a batched form that makes every world's setpoints in one pass can return (a formation's
    ``setpoints_batch``; the ``policy`` avoidance turning an environment's (B, N, 3) actions into
    setpoints), and what the next phase's batched form can take whole instead of stacking B
    records again (the built-in dynamics models' ``control_batch`` and ORCA's ``adjust_batch``
    do). It is a sequence of B per-world records, so code written for a list of records reads it
    as one: world b's record holds views of its rows of the stacked arrays (the B records are made
    together when one is first asked for, and are the same objects after).

    An edit in place of a world's record is the stacked record's too (they share memory). An
    attribute replaced in a handed-out record (``sp.pos = ...``) is not: :meth:`whole` then says
    ``None``, and a consumer falls back to the B records, which hold it.

    Args:
        whole: the stacked record, B x N agents, world b's agents in rows b N ... (b + 1) N - 1.
        worlds: B.

    Raises:
        ValueError: B is not positive, or does not divide the record's rows.
    """

    __slots__ = ("_whole", "_count", "_n", "_records", "_arrays")

    def __init__(self, whole: Setpoints, worlds: int) -> None:
        if worlds < 1 or whole.n % worlds:
            raise ValueError(f"a setpoint batch of {whole.n} agents cannot hold {worlds} worlds of equal size")
        self._whole, self._count, self._n = whole, worlds, whole.n // worlds
        self._records: list[Setpoints] | None = None  # the worlds' records, made all at once when first asked
        self._arrays: list[tuple] = []  # each record's arrays as they were made

    @classmethod
    def stack(cls, records: Sequence[Setpoints]) -> SetpointBatch:
        """B worlds' records (N agents each) stacked into one batch, world after world.

        Raises:
            ValueError: no records, records of different sizes, or some carrying jerk or snap
                and others not (one record has one set of fields).
        """
        if len({sp.n for sp in records}) != 1:
            raise ValueError(f"a setpoint batch stacks records of one size, not {sorted({sp.n for sp in records})}")

        def stacked(name: str) -> np.ndarray | None:
            arrays = [getattr(sp, name) for sp in records]
            if all(a is None for a in arrays):
                return None
            if any(a is None for a in arrays):
                raise ValueError(f"a setpoint batch stacks records that all carry {name}, or none")
            return np.concatenate(arrays)

        mode, pos, vel, acc, yaw = (cast(np.ndarray, stacked(name)) for name in ("mode", "pos", "vel", "acc", "yaw"))
        return cls(Setpoints(mode, pos, vel, acc, yaw, stacked("jerk"), stacked("snap")), len(records))

    def __len__(self) -> int:
        return self._count

    @overload
    def __getitem__(self, b: int) -> Setpoints: ...

    @overload
    def __getitem__(self, b: slice) -> list[Setpoints]: ...

    def __getitem__(self, b: int | slice) -> Setpoints | list[Setpoints]:
        try:
            return self._made()[b]
        except IndexError:
            raise IndexError(f"world {b} of a setpoint batch of {self._count}") from None

    def __iter__(self) -> Iterator[Setpoints]:
        return iter(self._made())

    def whole(self) -> Setpoints | None:
        """The stacked record (B N agents), or ``None`` where a world's record handed out no longer
        holds the views it was made with (an attribute of it was replaced): read, not edited."""
        if self._records is not None:
            for record, arrays in zip(self._records, self._arrays, strict=True):
                if not all(map(operator.is_, _fields(record), arrays)):
                    return None
        return self._whole

    def _made(self) -> list[Setpoints]:
        """Every world's record, views of its rows: made once, all together (a consumer that asks
        for one world's asks for the others'), by whole-array splits where the stacked arrays are
        contiguous (C loops, not a slice per world and field)."""
        if self._records is None:
            w, count, n = self._whole, self._count, self._n
            mode, pos, vel, acc, yaw = (_rows(a, count, n) for a in (w.mode, w.pos, w.vel, w.acc, w.yaw))
            jerk, snap = (None if a is None else _rows(a, count, n) for a in (w.jerk, w.snap))
            self._records = [Setpoints(mode[b], pos[b], vel[b], acc[b], yaw[b], None if jerk is None else jerk[b],
                                       None if snap is None else snap[b]) for b in range(count)]
            self._arrays = [_fields(record) for record in self._records]
        return self._records


def _rows(a: np.ndarray, worlds: int, n: int) -> list[np.ndarray]:
    """Views of ``a``'s rows, ``n`` a world: a split of the whole array where that is a view (a
    C-contiguous array), else a slice each."""
    if a.flags.c_contiguous:
        return list(a.reshape(worlds, n, *a.shape[1:]))
    return [a[b * n:(b + 1) * n] for b in range(worlds)]


def _fields(sp: Setpoints) -> tuple:
    """The record's arrays, in field order (``dataclasses.astuple`` would deep-copy them)."""
    return sp.mode, sp.pos, sp.vel, sp.acc, sp.yaw, sp.jerk, sp.snap
