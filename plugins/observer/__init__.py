"""Observers (monitors, metrics, recorders): every registered one runs in every run."""
