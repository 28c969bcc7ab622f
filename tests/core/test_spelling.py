"""One meaning of ``kind`` (issue #35): an event's kind and a disturbance model are chosen by ``name``
like every other plugin; ``kind`` still works until 0.9.0 with one deprecation warning naming the
key, both is one error line, the run record writes ``name`` and hashes as before, and
``Event.kind`` / ``Disturbance.kind`` are deprecated aliases of ``name``. The start layout is
``swarm.start.layout`` (``swarm.start.kind`` read until 0.9.0, hashed as before); a distribution's
family and a policy's action command lost their ``kind`` aliases' meaning the same way."""

from __future__ import annotations

import copy
import warnings

import pytest
from pydantic import ValidationError

from swarmscene import api
from swarmscene.core.errors import ConfigError, SwarmsceneDeprecationWarning, format_validation_error
from swarmscene.core.events import Event, EventConfig
from swarmscene.core.spelling import canonical_names, recorded_name
from swarmscene.plugin import Disturbance, DisturbanceParams
from swarmscene.plugins.disturbance.sensing_noise import SensingNoise
from swarmscene.plugins.event.hover import Hover
from swarmscene.runs.outputs import config_hash

_, REGISTRY = api.plugins()


def scenario_with(data: dict, event: dict, model: dict) -> dict:
    """``data`` (the default scenario) with one event and one disturbance model under key ``gps``."""
    data = copy.deepcopy(data)
    data["clock"]["duration"] = 1.0
    data["events"] = [{"at": 0.5, "agents": [1], **event}]
    data["disturbances"] = {"gps": {"pos_std": [0.1, 0.1, 0.1], **model}}
    return data


def test_name_chooses_an_event_kind_and_a_disturbance_model_without_a_warning(default_data):
    data = scenario_with(default_data, {"name": "hover"}, {"name": "sensing_noise"})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scenario = api.load(data, REGISTRY)
    assert scenario.config.events[0].name == "hover" and scenario.config.events[0].kind_class is Hover
    assert scenario.disturbances["gps"][0] is SensingNoise
    # the run record writes name, never kind
    assert scenario.data["events"] == [{"at": 0.5, "agents": [1], "name": "hover"}]
    assert scenario.data["disturbances"]["gps"]["name"] == "sensing_noise"
    assert "kind" not in scenario.data["disturbances"]["gps"]


def test_kind_still_chooses_them_with_exactly_one_deprecation_line_each(default_data):
    new = api.load(scenario_with(default_data, {"name": "hover"}, {"name": "sensing_noise"}), REGISTRY)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = api.load(scenario_with(default_data, {"kind": "hover"}, {"kind": "sensing_noise"}), REGISTRY)
    lines = [str(w.message) for w in caught if issubclass(w.category, SwarmsceneDeprecationWarning)]
    assert lines == [
        "events.0.kind is deprecated: write events.0.name (kind is accepted until 0.9.0)",
        "disturbances.gps.kind is deprecated: write disturbances.gps.name (kind is accepted until 0.9.0)",
    ]
    assert old.data == new.data  # mapped to name: the same scenario, recorded the same way
    assert config_hash(old.data) == config_hash(new.data)


@pytest.mark.parametrize(("event", "model", "line"), [
    ({"name": "hover", "kind": "hover"}, {"name": "sensing_noise"},
     "events.0.kind: kind and name both given: write events.0.name only (kind is its old spelling)"),
    ({"name": "hover"}, {"name": "sensing_noise", "kind": "dryden"},
     "disturbances.gps.kind: kind and name both given: write disturbances.gps.name only (kind is its old spelling)"),
])
def test_name_and_kind_both_given_is_one_error_line(default_data, event, model, line):
    with pytest.raises(ConfigError) as err:
        api.load(scenario_with(default_data, event, model), REGISTRY)
    assert err.value.lines == [line]


def test_kind_typed_over_a_shipped_file_that_says_name_is_that_error_naming_the_key_to_type():
    """``events.0.kind=stuck`` on the command line, over events/lead_fails.yaml's ``name: hover``."""
    with pytest.raises(ConfigError) as err:
        api.load(["events=lead_fails", "events.0.kind=stuck"], REGISTRY)
    assert err.value.lines == [
        "events.0.kind: kind and name both given: write events.0.name only (kind is its old spelling)"]
    assert api.load(["events=lead_fails", "events.0.name=stuck"], REGISTRY).config.events[0].name == "stuck"


def test_a_disturbance_without_name_is_the_model_its_key_names(default_data):
    data = copy.deepcopy(default_data)
    data["disturbances"] = {"sensing_noise": {}}
    scenario = api.load(data, REGISTRY)
    assert scenario.data["disturbances"]["sensing_noise"]["name"] == "sensing_noise"


def test_an_event_validated_on_its_own_reads_kind_with_the_warning():
    context = {"registry": REGISTRY}
    with pytest.warns(SwarmsceneDeprecationWarning, match=r"^events\[\]\.kind is deprecated: write events\[\]\.name"):
        old = EventConfig.model_validate({"at": 1.0, "agents": [0], "kind": "hover"}, context=context)
    assert old.model_dump() == EventConfig.model_validate(
        {"at": 1.0, "agents": [0], "name": "hover"}, context=context).model_dump()
    both = {"at": 1.0, "agents": [0], "kind": "hover", "name": "hover"}
    with pytest.raises(ValidationError) as err:
        EventConfig.model_validate(both, context=context)
    assert format_validation_error(err.value, EventConfig, both, "events.0") == [
        "events.0.kind: kind and name both given: write events[].name only (kind is its old spelling) (got 'hover')"]
    with pytest.warns(SwarmsceneDeprecationWarning, match="EventConfig.kind is deprecated: read EventConfig.name"):
        assert old.kind == "hover"


def test_event_name_is_the_kinds_name_and_event_kind_its_deprecated_alias():
    event = Hover.event(1.0, (2,))
    assert event.name == "hover" and event == Event(1.0, (2,), "hover", params=event.params, kind_class=Hover)
    with pytest.warns(SwarmsceneDeprecationWarning, match=r"Event.kind is deprecated: read Event.name"):
        assert event.kind == "hover"


def test_disturbance_kind_is_a_deprecated_alias_of_name():
    with pytest.warns(SwarmsceneDeprecationWarning, match="SensingNoise.kind is deprecated: read SensingNoise.name"):
        assert SensingNoise.kind == "sensing_noise"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert SensingNoise.name == "sensing_noise"


def test_a_model_declaring_kind_is_registered_under_it_with_a_warning():
    with pytest.warns(SwarmsceneDeprecationWarning, match="OldStyle declares kind = 'old_style': declare name"):
        class OldStyle(Disturbance):
            kind = "old_style"
            phase = "sense"
            Params = DisturbanceParams

    assert OldStyle.name == "old_style"
    with pytest.warns(SwarmsceneDeprecationWarning, match="OldStyle.kind is deprecated"):
        assert OldStyle.kind == "old_style"


def test_recorded_name_and_canonical_names_read_either_spelling():
    assert recorded_name({"at": 1.0, "name": "hover"}) == recorded_name({"at": 1.0, "kind": "hover"}) == "hover"
    assert recorded_name({"speed": 1.0}, "dryden") == "dryden" and recorded_name(None) is None
    new = {"events": [{"at": 1.0, "agents": [0], "name": "hover"}], "formation": {"name": "line"},
           "disturbances": {"gps": {"name": "sensing_noise"}, "dryden": {"speed": 1.0}}}
    old = {"events": [{"at": 1.0, "agents": [0], "kind": "hover"}], "formation": {"name": "line"},
           "disturbances": {"gps": {"kind": "sensing_noise"}, "dryden": {"speed": 1.0}}}
    assert canonical_names(new) == canonical_names(old) == old  # keyed kind, as first hashed
    assert new["events"][0] == {"at": 1.0, "agents": [0], "name": "hover"}  # the argument is not changed
    assert config_hash(new) == config_hash(old)


# -- the start layout: swarm.start.layout, swarm.start.kind read until 0.9.0 ---------------------
def with_start(data: dict, **start) -> dict:
    data = copy.deepcopy(data)
    data["swarm"] = {**data["swarm"], "n": 4, "start": {"spacing": 1.5, **start}}
    return data


def test_start_kind_still_lays_out_the_swarm_with_one_deprecation_line(default_data):
    new = api.load(with_start(default_data, layout="line"), REGISTRY)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = api.load(with_start(default_data, kind="line"), REGISTRY)
    lines = [str(w.message) for w in caught if issubclass(w.category, SwarmsceneDeprecationWarning)]
    assert lines == ["swarm.start.kind is deprecated: write swarm.start.layout (kind is accepted until 0.9.0)"]
    assert (old.initial_positions == new.initial_positions).all()
    assert new.initial_positions[:, 1].tolist() == [-2.25, -0.75, 0.75, 2.25]  # a line along +y, 1.5 m apart
    assert old.data == new.data and old.data["swarm"]["start"]["layout"] == "line"
    assert "kind" not in old.data["swarm"]["start"]


def test_start_kind_over_a_file_that_says_layout_wins(default_data):
    """An old command line (``swarm.start.kind=line``) composed over a preset spelt ``layout``."""
    with pytest.warns(SwarmsceneDeprecationWarning, match="swarm.start.kind is deprecated"):
        scenario = api.load(with_start(default_data, layout="grid", kind="line"), REGISTRY)
    assert scenario.config.swarm.start.layout == "line"


def test_a_bad_start_kind_names_the_key_typed_and_its_new_name(default_data):
    with pytest.warns(SwarmsceneDeprecationWarning), pytest.raises(ConfigError) as err:
        api.load(with_start(default_data, kind="spiral"), REGISTRY)
    assert err.value.lines == ["swarm.start.kind (now swarm.start.layout): must be one of 'line', 'grid', "
                               "'circle', 'explicit' or 'random' (got 'spiral')"]


def test_the_start_layout_hashes_as_its_old_key():
    """Run records and swarmscene-bench v1's frozen definitions were hashed with ``kind``."""
    layout = {"swarm": {"n": 2, "start": {"layout": "line", "spacing": 2.0}}}
    kind = {"swarm": {"n": 2, "start": {"kind": "line", "spacing": 2.0}}}
    assert canonical_names(layout) == canonical_names(kind) == kind
    assert config_hash(layout) == config_hash(kind)
    both = {"swarm": {"n": 2, "start": {"kind": "line", "layout": "grid"}}}  # kind wins, as validation reads it
    assert canonical_names(both) == {"swarm": {"n": 2, "start": {"kind": "line"}}}
    assert layout == {"swarm": {"n": 2, "start": {"layout": "line", "spacing": 2.0}}}  # not changed in place


def test_a_draws_family_and_a_policys_command_keep_kind_as_deprecated_aliases():
    from swarmscene.methods.policy.actions import ActionSpec
    from swarmscene.plugin import Draw

    draw = Draw.model_validate({"lognormal": [0.0, 0.5]})
    assert draw.family == "lognormal" and draw.families() == ["lognormal"]
    with pytest.warns(SwarmsceneDeprecationWarning, match=r"Draw.kind is deprecated: read Draw.family"):
        assert draw.kind == "lognormal"
    with pytest.warns(SwarmsceneDeprecationWarning, match=r"Draw.kinds\(\) is deprecated: call Draw.families\(\)"):
        assert draw.kinds() == ["lognormal"]
    spec = ActionSpec("acceleration", 2.0, 3.0, 0.1)
    assert spec.command == "acceleration"
    with pytest.warns(SwarmsceneDeprecationWarning, match="ActionSpec.kind is deprecated: read ActionSpec.command"):
        assert spec.kind == "acceleration"
