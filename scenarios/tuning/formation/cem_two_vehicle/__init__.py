"""cem_two_vehicle's tuning of each formation method (see scenarios/config.yaml)."""
