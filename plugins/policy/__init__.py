"""Policies (``avoidance.policy``), one registered module each."""
