"""indoor_building's tuning of each dynamics method (see scenarios/config.yaml)."""
