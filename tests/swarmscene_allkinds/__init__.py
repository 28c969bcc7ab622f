"""A third-party package registering one component of every kind, written from docs/plugins.md and
importing nothing of the engine but ``swarmscene.plugin`` (tests/test_plugin_kinds.py installs it
through a ``swarmscene`` entry point and runs it)."""
