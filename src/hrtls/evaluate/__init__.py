"""Accuracy metrics, JSON reports and plots of estimated trajectories against ground truth."""
