"""The numerics of the built-in disturbance models (``plugins/disturbance/``): wind, sensing noise and
communication, each vectorised over agents (or links) with its published source.

* :mod:`.atmosphere`: MIL-F-8785C / MIL-HDBK-1797: the 1-cosine discrete gust, the mean-wind log
  profile, Dryden turbulence (scales, intensities, exactly discretised shaping filters);
* :mod:`.wind`: what the wind models share: their options (``heading``, ``moment_arm``) and the
  direction of a heading;
* :mod:`.noise`: the first-order Gauss-Markov error of a position estimate;
* :mod:`.links`: delays in guidance ticks (fixed, hop-proportional as in thesis section 4.2, random)
  and packet-loss processes (Bernoulli, Gilbert-Elliott, range).

The kernel's phases and the broadcast channel that carries the messages are the engine's
(:mod:`swarmscene.core.disturbances`); this package imports no plugin.
"""
