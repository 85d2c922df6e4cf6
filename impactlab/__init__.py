"""impactlab: simulated impact experiments (record to MCAP, analyze in polars, replay in Rerun)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("impactlab")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
