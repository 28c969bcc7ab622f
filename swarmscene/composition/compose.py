"""The config tree composed with Hydra, as plain data: what ``api.compose`` returns, and what the
suite, the tools and the sweeps compose with (they sit below the public API and do not import it)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

from ..core.errors import ConfigError

CONFIG_MODULE = "swarmscene.scenarios"
"""The package of the config tree (scenarios/)."""
CONFIG_NAME = "config"
"""Its primary config (scenarios/config.yaml)."""


def compose(overrides: Sequence[str] = ()) -> dict[str, Any]:
    """Compose the config tree with Hydra overrides; return plain data without the ``hydra`` node.

    Every documented option is set with plain ``key=value`` (rewritten to ``++key=value``,
    :func:`swarmscene.composition.searchpath.plain_overrides`), whether or not the composed YAML holds it.
    A composition that fails (an unknown option, a value that does not parse or resolve) raises
    :class:`~swarmscene.core.errors.ConfigError` with the command line's one-line wording.
    """
    from hydra import compose as hydra_compose
    from hydra import initialize_config_module
    from omegaconf import OmegaConf

    from .searchpath import plain_overrides, register_search_path

    register_search_path()
    try:
        with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
            cfg = hydra_compose(config_name=CONFIG_NAME, overrides=plain_overrides(overrides))
        return cast("dict[str, Any]", OmegaConf.to_container(cfg, resolve=True))  # the root is a mapping
    except ConfigError:
        raise
    except Exception as exc:  # Hydra's multi-line wording: the command line's one line instead
        from .hydra_errors import hydra_error_line

        line = hydra_error_line(exc)  # the command line's reading (an unresolvable value included)
        if line is None:
            raise
        raise ConfigError([line]) from exc
