"""`impactlab calibrate`: record a grid of calibrated impacts, measure e from the logs.

Record-side tool: it generates specs (`grid`), records and analyzes them with the analysis
stage (`run`), plots (`plots`) and writes the results (`command`).
"""
