"""Estimation: IMM Kalman filters of object poses, their motion models, held objects, the estimate report."""
