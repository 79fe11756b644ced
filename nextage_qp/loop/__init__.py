"""The control loop: simulation, the servo tick, PD torques, jerk-limited references, stepping, recorder."""
