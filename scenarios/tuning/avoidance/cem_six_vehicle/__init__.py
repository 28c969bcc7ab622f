"""cem_six_vehicle's tuning of each avoidance method (see scenarios/config.yaml)."""
