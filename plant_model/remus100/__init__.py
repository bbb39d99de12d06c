"""The nonlinear REMUS 100 (model ``remus100-6dof``, docs/remus100-6dof.md) and the models
derived from it (``remus100-fitted``).

- :mod:`.rigid_body`: the 6-DOF mathematics (M_RB, Coriolis, kinematics, restoring, RK4);
- :mod:`.dynamics`: the REMUS 100 itself (:class:`~.dynamics.Remus100`, its derivative);
- :mod:`.autopilot`: the inner loops behind the linear model's force interface;
- :mod:`.kernel`: the same equations compiled by numba;
- :mod:`.plant`: one vehicle sampled at h;
- :mod:`.models`: ``remus100-6dof`` and ``remus100-fitted`` as scenario models (the
  entries of :mod:`plant_model.vehicle_models` point here);
- ``auv_remus6dof_slave.py``: the FMU ``AuvRemus6dof``; ``auv_remus6dof_actuated_slave.py``:
  ``AuvRemus6dofActuated`` (actuator commands in, model ``remus100-6dof-guided``); the code
  they share in ``remus6dof_slave_base.py``.

Nothing is imported here, so that importing one module does not load numba.
"""
