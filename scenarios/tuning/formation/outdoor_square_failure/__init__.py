"""outdoor_square_failure's tuning of each formation method (see scenarios/config.yaml)."""
