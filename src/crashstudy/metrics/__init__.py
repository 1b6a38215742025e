"""Crash criteria of the metrics: block: per-step record, SAE J211 filter, HIC, clips, OLC, DRI."""
