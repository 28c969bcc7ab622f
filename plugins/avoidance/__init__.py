"""Avoidance methods (``avoidance=NAME``), one registered module each."""
