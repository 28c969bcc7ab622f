"""flocking's tuning of each formation method (see scenarios/config.yaml)."""
