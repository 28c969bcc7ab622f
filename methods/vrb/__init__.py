"""Virtual Rigid Body formations (Zhou and Schwager): C4 body trajectories in SE(3), the
transformation law between formations (eq. 7-8) and the reconstructed air show of section IV.
Used by the ``virtual_rigid_body`` formation plugin."""
