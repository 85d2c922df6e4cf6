"""Analysis stage: MCAP logs -> polars frames -> bounces, energy, collisions, tables, report."""
