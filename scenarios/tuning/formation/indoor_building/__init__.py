"""indoor_building's tuning of each formation method (see scenarios/config.yaml)."""
