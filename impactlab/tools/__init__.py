"""Tools over logs: `info`, `diff`, and the comparison within tolerances (`compare`) they share
with the golden logs (`impactlab.golden`) and the pytest plugin (`impactlab.testing`)."""

DEFAULT_ATOL = 1e-9
DEFAULT_RTOL = 1e-9
DEFAULT_IGNORED_META = ("impactlab_version",)  # a release with the same physics: an equal log
