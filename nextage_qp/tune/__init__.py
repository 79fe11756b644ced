"""Automatic tuning: Optuna studies over a sweep's episodes or joint step responses (``nextage-qp tune``)."""
