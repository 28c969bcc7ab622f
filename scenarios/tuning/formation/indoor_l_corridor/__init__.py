"""indoor_l_corridor's tuning of each formation method (see scenarios/config.yaml)."""
