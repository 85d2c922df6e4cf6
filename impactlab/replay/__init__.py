"""Replay stage: logs and their analysis -> Rerun recordings (.rrd)."""
