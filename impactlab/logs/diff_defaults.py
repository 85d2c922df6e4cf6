"""The defaults of comparing two logs, apart so that the command line's parser reads them
without importing the comparison (`impactlab.logs.diff_result`)."""

from __future__ import annotations

DEFAULT_ATOL = 1e-9
DEFAULT_RTOL = 1e-9
DEFAULT_IGNORED_META = ("impactlab_version",)
