"""Disturbance models (``disturbances=[...]``), one registered module each."""
