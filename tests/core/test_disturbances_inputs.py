"""Every option of every disturbance model at its boundary values either runs or is refused with
the one-line ConfigError naming ``disturbances.<key>.<option>`` (nothing else is raised)."""

from __future__ import annotations

import copy

import pytest

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.plugins.disturbance.comm_delay import CommDelay
from swarmscene.plugins.disturbance.constant_wind import ConstantWind
from swarmscene.plugins.disturbance.dryden import Dryden
from swarmscene.plugins.disturbance.gust import Gust
from swarmscene.plugins.disturbance.packet_loss import PacketLoss
from swarmscene.plugins.disturbance.sensing_noise import SensingNoise

VALUES = [0, -0.0, -1, 1e308, 5e-324, float("nan"), float("inf"), True, None, "x"]
MODELS = {m.name: m for m in (ConstantWind, Gust, Dryden, SensingNoise, CommDelay, PacketLoss)}
CASES = [(kind, name) for kind, cls in MODELS.items() for name in cls.Params.model_fields]


@pytest.fixture(scope="module")
def small(default_data):
    data = copy.deepcopy(default_data)
    data["swarm"]["n"] = 3
    data["clock"]["duration"] = 0.2
    data["output"]["summary"] = False
    return data


@pytest.mark.parametrize("kind, name", CASES)
def test_boundary_values_run_or_are_one_line(small, kind, name):
    for dynamics in ("double_integrator", "quadrotor"):
        for value in VALUES:
            data = copy.deepcopy(small)
            data["dynamics"] = {"name": dynamics}
            tuple_field = isinstance(MODELS[kind].Params.model_fields[name].default, tuple)
            data["disturbances"] = {"m": {"name": kind, name: [value] * 3 if tuple_field else value}}
            try:
                api.run(data)
            except ConfigError as exc:
                assert exc.lines and all(line.startswith(f"disturbances.m.{name}") for line in exc.lines), exc.lines
