"""Dynamics models (``dynamics=NAME``), one registered module each."""
