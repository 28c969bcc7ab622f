"""The ``battery`` disturbance model: charge, voltage sag, the thrust it limits, and running out.

Numerics and sources: :mod:`swarmscene.methods.physics.battery`. A force phase model: each
physics step it draws the power of each vehicle's thrust τ (:mod:`swarmscene.methods.physics.thrust`)
from its cell, and returns the thrust the cell cannot give, -max(0, m|τ| - T_max(V)) / m along τ
(the rotors' thrust capped at what the sagging voltage allows). A vehicle whose cell runs out
(charge 0, or an open-circuit voltage at the cut-off) loses its thrust: a ``battery_depleted``
event (a failure) at the end of that tick, and it falls under its dynamics (onto
``environment.floor`` when there is one).

Metrics: ``min_charge`` (the lowest state of charge, 0..1), ``min_voltage`` (V),
``depleted`` (vehicles that ran out), ``first_depleted_time`` (s, after one ran out).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, model_validator

from swarmscene.methods.physics import battery as cell
from swarmscene.methods.physics import crazyflie as cf
from swarmscene.plugin import Disturbance, DisturbanceParams, Event, hookimpl


class Battery(Disturbance):
    """A 1S LiPo per vehicle: Coulomb counting, sag through R_i, T_max ∝ V², cut-off."""

    name = "battery"
    phase = "force"

    class Params(DisturbanceParams):
        capacity: float = Field(cf.BATTERY_CAPACITY, gt=0, le=1e4, description="Q, Ah (Crazyflie 2.1: 0.25)")
        charge: float = Field(1.0, ge=0, le=1, description="state of charge at t = 0, 0..1")
        v_full: float = Field(cf.BATTERY_FULL, gt=0, le=1e3, description="V_f: open-circuit voltage full, V (4.2)")
        v_empty: float = Field(cf.BATTERY_EMPTY, gt=0, le=1e3,
                               description="V_e: open-circuit voltage empty, V (3.0)")
        resistance: float = Field(cf.BATTERY_RESISTANCE, gt=0, le=1e3,
                                  description="R_i: internal resistance, Ohm (0.2)")
        cutoff: float = Field(cell.CUTOFF, ge=0, le=1e3,
                              description="V_c: the terminal voltage never drawn under, V (2.8)")
        hover_power: float = Field(
            cell.HOVER_POWER, gt=0, le=1e6, description="P_h: electrical power at hover, W (Crazyflie 5.88: "
            "a full cell then hovers the datasheet's 7 min)")
        thrust_to_weight: float = Field(cf.THRUST_TO_WEIGHT, gt=1, le=100, description="(T/W)_max at V_f (2.25)")
        mass: float = Field(cf.MASS, gt=0, le=1e4, description="m, kg (0.027)")
        k_T: float = Field(cf.K_T, gt=0, description="k_T, N/(rad/s)^2, to read the rotors' thrust")

        @model_validator(mode="after")
        def _voltages_ordered(self) -> Battery.Params:
            if not self.v_empty < self.v_full:
                raise ValueError(f"v_empty: must be below v_full = {self.v_full} V (got {self.v_empty})")
            return self

    params: Params

    def __init__(self, params: Battery.Params, ctx) -> None:
        super().__init__(params, ctx)
        from swarmscene.methods.physics.kernels import battery_step  # numba: imported when built
        from swarmscene.methods.physics.thrust import thrust_per_mass

        self._thrust, self._step = thrust_per_mass, battery_step
        self.dt = ctx.physics_step
        self.weight = params.mass * cf.GRAVITY
        self.charge = np.full(ctx.n, float(params.charge))
        self.voltage = cell.open_circuit_voltage(self.charge, params.v_full, params.v_empty)
        self.lowest = float(params.v_full)  # the lowest terminal voltage over the run, V
        self.depleted = np.zeros(ctx.n, dtype=bool)
        self._new: list[int] = []
        self.first: float | None = None

    def force(self, world, t):
        """The thrust the cells cannot give, per mass (N, 3), m/s^2; the charge drawn (one compiled
        pass, :func:`swarmscene.methods.physics.kernels.battery_step`)."""
        p = self.params
        tau = np.ascontiguousarray(self._thrust(world, p.k_T, p.mass), dtype=np.float64)
        self.voltage, cut, out, lowest = self._step(
            self.charge, self.depleted, tau, self.dt, p.mass, self.weight, p.capacity, p.v_full, p.v_empty,
            p.resistance, p.cutoff, p.hover_power, p.thrust_to_weight)
        self.lowest = min(self.lowest, lowest)
        if out.any():
            self._new += np.flatnonzero(out).tolist()
        return cut

    def raised(self, world, t):
        """A ``battery_depleted`` event for the vehicles that ran out during this tick."""
        if not self._new:
            return []
        agents, self._new = tuple(sorted(set(self._new))), []
        if self.first is None:
            self.first = float(t)
        return [Event(float(t), agents, cell.BatteryDepleted.name, kind_class=cell.BatteryDepleted)]

    def metrics(self):
        """``min_charge``, ``min_voltage`` (V), ``depleted`` and ``first_depleted_time`` (s)."""
        out = {"min_charge": float(self.charge.min(initial=1.0)),
               "min_voltage": self.lowest,
               "depleted": int(self.depleted.sum())}
        if self.first is not None:
            out["first_depleted_time"] = self.first
        return out


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`Battery` to the registry, so that ``disturbances=[battery]`` chooses it."""
    register(Battery)
