"""Formations (``formation=NAME``), one registered module each."""
