"""Tools over logs: `info`, `diff`, and the comparison within tolerances (`compare`)."""

DEFAULT_ATOL = 1e-9
DEFAULT_RTOL = 1e-9
DEFAULT_IGNORED_META = ("impactlab_version",)  # a release with the same physics: an equal log
