"""cem_multi_failure's tuning of each formation method (see scenarios/config.yaml)."""
