"""The numerics of each source system, one package per system, importable on their own.

Plugin modules in ``swarmscene.plugins`` are thin adapters (``name``, ``Params``, the contract
methods) over these packages. A method package imports ``swarmscene.core`` and other method
packages, never a plugin.
"""
