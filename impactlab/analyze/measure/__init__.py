"""Measurement: each quantity of a batch of runs from the logs' frames to frames (contacts,
impacts, bounces, collisions, energy, flights); no table is written and no sentence is
chosen here. `analysis.analyze_runs` runs them in order for a batch of runs."""
