"""cem_two_vehicle's tuning of each dynamics method (see scenarios/config.yaml)."""
