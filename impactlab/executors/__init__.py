"""Executors: run a function over work items here (`local`) or on a Ray cluster (`ray`).

Owns: the `Executor` protocol, the local executor and the Ray executor (`ray`, imported
only when asked for). May import: `impactlab.errors` and Ray. Must not import: any stage
(record, analyze, replay, calibrate) or the log format; the stages build their tasks on it.
"""
