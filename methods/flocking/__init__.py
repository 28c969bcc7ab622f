"""Reynolds flocking (Reynolds 1987, as Mesa's BoidFlockers example steers): the compiled steer of
the ``reynolds_flocking`` formation (:mod:`.kernels`)."""
