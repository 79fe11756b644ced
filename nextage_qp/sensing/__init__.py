"""Sensing: the measured-state seam, faulty sensors and shoves, the cameras and the perception block."""
