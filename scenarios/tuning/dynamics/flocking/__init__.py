"""flocking's tuning of each dynamics method (see scenarios/config.yaml)."""
