"""cem_six_vehicle's tuning of each dynamics method (see scenarios/config.yaml)."""
