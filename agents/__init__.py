"""Training, baselines and evaluation of stick-slip suppression controllers."""
