"""indoor_l_corridor's tuning of each dynamics method (see scenarios/config.yaml)."""
