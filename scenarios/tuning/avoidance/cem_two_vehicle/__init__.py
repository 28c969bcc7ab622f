"""cem_two_vehicle's tuning of each avoidance method (see scenarios/config.yaml)."""
