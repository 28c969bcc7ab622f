"""Map generators (``environment.generator``), one registered module each."""
