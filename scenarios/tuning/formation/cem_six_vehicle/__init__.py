"""cem_six_vehicle's tuning of each formation method (see scenarios/config.yaml)."""
