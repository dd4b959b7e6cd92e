"""Evaluation of trained models and baselines on the UAV coverage environment, with the report's figures."""
