"""Quadrotor models and controllers: the 6-DOF rigid body (thesis eq. 3.4-3.16), differential
flatness, the geometric SE(3) controller, and the thesis' discrete controllers with pole-placement
gains (section 3.3). Used by the ``quadrotor`` and ``double_integrator`` dynamics plugins."""
