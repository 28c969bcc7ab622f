"""Reference implementations the tests check the engine against (not shipped in the package).

``tests/`` is on pytest's ``pythonpath`` (pyproject.toml), so a test imports ``oracles.<name>``.
"""
