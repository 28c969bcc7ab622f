"""cem_multi_failure's tuning of each dynamics method (see scenarios/config.yaml)."""
