"""One spelling of a chosen plugin's name: ``name``, for every kind (issue #35).

A scenario chooses every plugin by ``name`` (``formation: {name: hex_lattice}``), an event's kind and
a disturbance model too::

    events: [{at: 3.0, agents: [2], name: motor_failure, rotor: 0}]
    disturbances: {gps: {name: sensing_noise, pos_std: [2.1, 2.1, 4.2]}}

Until 0.6.0 those two were spelt ``kind``. Three places still meet that spelling:

* a scenario (:func:`renamed_kind`): ``kind`` is read as ``name`` until :data:`KIND_UNTIL`, with one
  :class:`~.errors.SwarmsceneDeprecationWarning` line naming the key; both given is one error line;
* a run directory recorded before (:func:`recorded_name`): every reader of a recorded event or
  disturbance model takes its plugin name from either key;
* a hash (:func:`canonical_names`): the config hash of a run and the definitions of a frozen
  benchmark suite (``swarmscene/suite/v1.json``) key the plugin name ``kind``, as they were first
  hashed, so a spelling changes no hash and a task means what it meant.

``kind`` had a third meaning until 0.7.x, the swarm's start layout. It is ``swarm.start.layout``
now (``line``, ``grid``, ``circle``, ``explicit``, ``random``); ``swarm.start.kind`` is read until
:data:`KIND_UNTIL` (:class:`~.config.StartConfig`, with one deprecation line) and hashed as
``kind`` by :func:`canonical_names`, like the plugin names. So ``kind`` means one thing, the kind
of a plugin (formation, avoidance, dynamics, event, ...).
"""

from __future__ import annotations

import warnings
from typing import Any

from .errors import SwarmsceneDeprecationWarning

NAME = "name"
"""The key of a chosen plugin's name, for every kind."""
KIND = "kind"
"""Its older spelling for an event's kind and a disturbance model (until :data:`KIND_UNTIL`)."""
KIND_UNTIL = "0.9.0"
"""The release that no longer reads ``kind`` in its old meanings (a plugin's name, the start layout)."""

LAYOUT = "layout"
"""The key of the swarm's start layout (``swarm.start.layout``)."""
START_RENAMES = {KIND: LAYOUT}
"""The start layout's old key -> its key (read by :class:`~.config.StartConfig`)."""


def renamed_kind(node: Any, where: str) -> Any:
    """An event's or a disturbance model's config ``node`` with its plugin name under ``name``.

    ``kind`` given alone is renamed, with the warning ``<where>.kind is deprecated: write
    <where>.name (kind is accepted until 0.9.0)``; anything that is not a mapping, or has no
    ``kind``, is returned as it is.

    Raises:
        ValueError: ``kind`` and ``name`` both given (``kind and name both given: write
            <where>.name only``; the caller puts the key ``<where>.kind`` before it). On the
            command line that is ``<where>.kind=...`` over a file that says ``name``.
    """
    if not isinstance(node, dict) or KIND not in node:
        return node
    if NAME in node:
        raise ValueError(f"{KIND} and {NAME} both given: write {where}.{NAME} only ({KIND} is its old spelling)")
    warnings.warn(f"{where}.{KIND} is deprecated: write {where}.{NAME} ({KIND} is accepted until {KIND_UNTIL})",
                  SwarmsceneDeprecationWarning, stacklevel=3)
    return {(NAME if k == KIND else k): v for k, v in node.items()}


def recorded_name(node: Any, default: Any = None) -> Any:
    """The plugin name of a recorded event or disturbance model (a mapping of a run's
    ``config.yaml``): its ``name``, or its ``kind`` as recorded until 0.6.0; ``default`` when it
    has neither or is not a mapping."""
    if not isinstance(node, dict):
        return default
    return node.get(NAME, node.get(KIND, default))


def canonical_names(config: Any) -> Any:
    """``config`` (composed or recorded) with each event's and each disturbance model's plugin name
    keyed ``kind``, and the start layout ``swarm.start.kind``, as run records and suite definitions
    were first hashed: the form every hash and every comparison with a frozen definition reads,
    whichever spelling a file has. An event or a model giving both keys is left as it is (validation
    refuses it); a start giving both keeps ``kind``, which validation reads. ``config`` itself is
    not changed."""
    return _respelt(config, LAYOUT, KIND, NAME)


def current_names(config: Any) -> Any:
    """:func:`canonical_names` undone: each event's and disturbance model's plugin name keyed
    ``name`` and the start layout ``swarm.start.layout``, as this version writes them (a frozen
    suite definition, kept in the canonical form, loaded by today's validation without its
    deprecation warnings). ``config`` itself is not changed."""
    return _respelt(config, KIND, LAYOUT, KIND)


def _respelt(config: Any, start_from: str, start_to: str, name_from: str) -> Any:
    """``config`` with the start layout's key ``start_from`` renamed ``start_to`` (a start giving
    both keeps ``kind``), and each event's and disturbance model's plugin name keyed ``name_from``
    renamed to the other spelling (a node giving both is left as it is)."""
    if not isinstance(config, dict):
        return config
    out = dict(config)
    swarm = config.get("swarm")
    if isinstance(swarm, dict) and isinstance(swarm.get("start"), dict) and start_from in swarm["start"]:
        start = swarm["start"]
        value = start[KIND] if KIND in start else start[start_from]  # with both, kind wins (an old command line)
        keyed = {}
        for k, v in start.items():
            if k == start_from:
                keyed[start_to] = value
            elif k != start_to:  # the other spelling, if given too: its value is the one above
                keyed[k] = v
        out["swarm"] = {**swarm, "start": keyed}
    name_to = KIND if name_from == NAME else NAME
    events = config.get("events")
    if isinstance(events, list):
        out["events"] = [_keyed(e, name_from, name_to) for e in events]
    models = config.get("disturbances")
    if isinstance(models, dict):
        out["disturbances"] = {key: _keyed(node, name_from, name_to) for key, node in models.items()}
    return out


def _keyed(node: Any, old: str, new: str) -> Any:
    """A plugin node with its name under ``new`` instead of ``old`` (as it is when it has both or none)."""
    if not isinstance(node, dict) or old not in node or new in node:
        return node
    return {(new if k == old else k): v for k, v in node.items()}
