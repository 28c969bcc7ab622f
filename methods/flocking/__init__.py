"""Reynolds flocking (Reynolds 1987, as Mesa's BoidFlockers example steers) for the
``reynolds_flocking`` formation: the rule (:mod:`.steering`), the periodic space (:mod:`.torus`)
and the compiled steer and seam pairs (:mod:`.kernels`)."""
