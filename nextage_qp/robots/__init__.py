"""Robots: robot files, the Robot model of a composed scene, its cameras and gains, `robot init` and `robot check`."""
