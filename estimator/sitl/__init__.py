"""SITL: start ArduCopter's (and PX4's) software-in-the-loop binary, fly it, record the flight.

- :mod:`estimator.sitl.launch`: find the binary and its parameter file, pick a free
  instance, run it in a scratch directory;
- :mod:`estimator.sitl.pilot`: a pymavlink ground station that flies it by the autopilot's
  own clock (``time_boot_ms``) and switches the simulator's effects (wind, gripper payload);
- :mod:`estimator.sitl.scenarios`: flights as data;
- :mod:`estimator.sitl.pack`: SITL's simulated pack (its voltage table) and a mislabelled,
  aged or partly charged pack to fly;
- :mod:`estimator.sitl.recorder`: one scenario → ``flight.tlog``, DataFlash ``flight.BIN``
  and ``truth.json`` (``uav-energy sitl-record``);
- :mod:`estimator.sitl.px4`: PX4 SITL with its built-in SIH quadrotor, on a free instance;
- :mod:`estimator.sitl.px4_pilot`: a ground station that flies it by PX4's clock, and a pack
  whose current follows PX4's motor outputs, fed into PX4.

See docs/sitl.md.
"""
