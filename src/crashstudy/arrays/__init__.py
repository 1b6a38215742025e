"""From validated objects to plain arrays: topology, per-variant parameters, time steps."""
