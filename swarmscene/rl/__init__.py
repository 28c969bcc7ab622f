"""The RL environments' machinery below their entry point (``swarmscene.env``): one episode, its
options and rewards (:mod:`~swarmscene.rl.episode`), a vector environment's worlds ticked as one
batch (:mod:`~swarmscene.rl.worlds`), and those worlds stepped by worker processes
(:mod:`~swarmscene.rl.workers`)."""
