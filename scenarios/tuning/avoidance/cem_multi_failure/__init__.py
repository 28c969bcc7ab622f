"""cem_multi_failure's tuning of each avoidance method (see scenarios/config.yaml)."""
