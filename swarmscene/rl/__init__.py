"""The RL environments' machinery below their entry point (``swarmscene.env``): a vector
environment's worlds stepped by worker processes (:mod:`swarmscene.rl.workers`)."""
