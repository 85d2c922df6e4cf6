"""Executors: run a function over work items here (`local`), over worker processes of this
machine (`processes`) or on a Ray cluster (`ray`).

Owns: the `Executor` protocol, the local, processes and Ray executors (`ray`, imported
only when asked for). May import: `impactlab.errors` and Ray. Must not import: any stage
(record, analyze, replay, calibrate) or the log format; the stages build their tasks on it.
"""
