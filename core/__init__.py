"""The engine: the scenario schema and its validation, the kernel, the plugin contracts and registry."""
