"""A preset's per-method tuning (see scenarios/config.yaml)."""
